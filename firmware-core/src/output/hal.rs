//! Example [`SetpointSink`]s on embedded-hal 1.0 (feature `embedded-hal`).
//!
//! - [`SpiSetpointSink`]: each setpoint as one fixed-size [`Frame`] written
//!   to an [`SpiDevice`] (one transaction, chip select framed by the device)
//!   — e.g. to servo drives on a shared command bus.
//! - [`StrobeSink`]: any sink plus an [`OutputPin`] toggled after each
//!   delivered setpoint — a servo-sync strobe the drives latch on.
//!
//! They are examples of the output trait on the board-independent HAL
//! traits, not a drive protocol: a real drive defines its own frame.
//!
//! # Frame (20 bytes, all little-endian)
//!
//! | offset | bytes | field | encoding |
//! |---:|---:|---|---|
//! | 0 | 2 | sequence number | `u16`, +1 per frame sent, wraps 65535 → 0 |
//! | 2 | 4 | x | `i32` nanometres, `round(pos_mm[0] · 10⁶)` (half away from 0) |
//! | 6 | 4 | y | `i32` nm |
//! | 10 | 4 | z | `i32` nm |
//! | 14 | 4 | feed | `u32` µm/s, `round(feed_mm_s · 10³)` |
//! | 18 | 2 | CRC | CRC-16/IBM-3740 ("CCITT-FALSE": poly 0x1021, init 0xFFFF, not reflected, xorout 0; check value 0x29B1) over bytes 0..18 |
//!
//! Range: positions within ±2,147.483647 mm (i32 nm), the feed within
//! 0 ..= 4,294,967.295 mm/s. A value outside (or NaN) is refused with
//! [`SpiSinkError::OutOfRange`] / [`SpiSinkError::FeedOutOfRange`] before
//! anything is sent: never wrapped, saturated or panicked on. The setpoint's
//! time, s and u are not sent (the drive's clock is the strobe or the frame
//! itself; the sequence number shows lost frames).
//!
//! The sequence number advances only when the SPI write succeeded: after an
//! [`SpiSinkError::Spi`] the caller may retry the same setpoint with the same
//! number (the drive drops duplicates by number).
//!
//! ```
//! use firmware_core::interp::Setpoint;
//! use firmware_core::output::hal::{Frame, FRAME_LEN};
//!
//! let sp = Setpoint { t_s: 0.0, s_mm: 0.0, u: 0.0, feed_mm_s: 12.5, pos_mm: [1.0, -2.0, 0.000_000_4] };
//! let frame = Frame::from_setpoint(7, &sp).unwrap();
//! assert_eq!(frame.pos_nm, [1_000_000, -2_000_000, 0]);
//! let bytes: [u8; FRAME_LEN] = frame.to_bytes();
//! assert_eq!(Frame::from_bytes(&bytes), Some(frame)); // CRC verified
//! ```

use core::convert::Infallible;
use core::fmt;
use embedded_hal::digital::{OutputPin, PinState};
use embedded_hal::spi::SpiDevice;

use crate::interp::setpoint::Setpoint;
use crate::output::SetpointSink;

/// Bytes of one frame.
pub const FRAME_LEN: usize = 20;
/// Bytes covered by the CRC (all but the CRC).
pub const FRAME_BODY_LEN: usize = FRAME_LEN - 2;

/// The frame CRC: CRC-16/IBM-3740 (poly 0x1021, init 0xFFFF, not reflected).
pub const FRAME_CRC: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);

/// Why a setpoint was not sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SpiSinkError<E> {
    /// The SPI transaction failed (the sequence number did not advance).
    Spi(E),
    /// A position is NaN or outside ±2,147.483647 mm (the i32 nm range).
    OutOfRange {
        /// 0 = x, 1 = y, 2 = z.
        axis: u8,
    },
    /// The feed is NaN, negative or above `u32::MAX` µm/s.
    FeedOutOfRange,
}

impl<E> SpiSinkError<E> {
    /// The same range error for another SPI error type.
    fn widen(e: SpiSinkError<Infallible>) -> Self {
        match e {
            SpiSinkError::Spi(never) => match never {},
            SpiSinkError::OutOfRange { axis } => SpiSinkError::OutOfRange { axis },
            SpiSinkError::FeedOutOfRange => SpiSinkError::FeedOutOfRange,
        }
    }
}

impl<E: fmt::Debug> fmt::Display for SpiSinkError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SpiSinkError::Spi(e) => write!(f, "SPI write failed: {e:?}"),
            SpiSinkError::OutOfRange { axis } => {
                write!(f, "axis {axis}: position outside the i32 nanometre range")
            }
            SpiSinkError::FeedOutOfRange => write!(f, "feed outside the u32 µm/s range"),
        }
    }
}

/// One setpoint as sent: see the module docs for the byte layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Frame {
    /// Sequence number.
    pub seq: u16,
    /// x, y, z, nm.
    pub pos_nm: [i32; 3],
    /// Feed, µm/s.
    pub feed_um_s: u32,
}

/// `round(x)` if it is an integer in `lo ..= hi` (false for NaN).
fn rounded_in(x: f64, lo: f64, hi: f64) -> Option<f64> {
    let r = libm::round(x);
    (lo..=hi).contains(&r).then_some(r)
}

impl Frame {
    /// The frame for `sp` with sequence number `seq`; range errors as in
    /// [`SpiSinkError`] (no SPI involved: the error type is uninhabited).
    pub fn from_setpoint(seq: u16, sp: &Setpoint) -> Result<Frame, SpiSinkError<Infallible>> {
        let mut pos_nm = [0i32; 3];
        for (axis, (out, mm)) in [0u8, 1, 2].into_iter().zip(pos_nm.iter_mut().zip(sp.pos_mm)) {
            let nm = rounded_in(mm * 1e6, f64::from(i32::MIN), f64::from(i32::MAX))
                .ok_or(SpiSinkError::OutOfRange { axis })?;
            // In range and integral: the cast is exact.
            *out = nm as i32;
        }
        let feed =
            rounded_in(sp.feed_mm_s * 1e3, 0.0, f64::from(u32::MAX)).ok_or(SpiSinkError::FeedOutOfRange)?;
        Ok(Frame {
            seq,
            pos_nm,
            feed_um_s: feed as u32,
        })
    }

    /// The 18 bytes before the CRC.
    fn body(&self) -> [u8; FRAME_BODY_LEN] {
        let [x, y, z] = self.pos_nm;
        let fields = self
            .seq
            .to_le_bytes()
            .into_iter()
            .chain(x.to_le_bytes())
            .chain(y.to_le_bytes())
            .chain(z.to_le_bytes())
            .chain(self.feed_um_s.to_le_bytes());
        let mut body = [0u8; FRAME_BODY_LEN];
        body.iter_mut().zip(fields).for_each(|(b, v)| *b = v);
        body
    }

    /// The wire bytes, CRC included.
    pub fn to_bytes(&self) -> [u8; FRAME_LEN] {
        let body = self.body();
        let crc = FRAME_CRC.checksum(&body).to_le_bytes();
        let mut out = [0u8; FRAME_LEN];
        out.iter_mut()
            .zip(body.into_iter().chain(crc))
            .for_each(|(b, v)| *b = v);
        out
    }

    /// Decode wire bytes (the drive's side); `None` if the CRC does not match.
    pub fn from_bytes(bytes: &[u8; FRAME_LEN]) -> Option<Frame> {
        let (body, crc) = bytes.split_last_chunk::<2>()?;
        if FRAME_CRC.checksum(body) != u16::from_le_bytes(*crc) {
            return None;
        }
        let (seq, rest) = body.split_first_chunk::<2>()?;
        let (x, rest) = rest.split_first_chunk::<4>()?;
        let (y, rest) = rest.split_first_chunk::<4>()?;
        let (z, rest) = rest.split_first_chunk::<4>()?;
        let (feed, _) = rest.split_first_chunk::<4>()?;
        Some(Frame {
            seq: u16::from_le_bytes(*seq),
            pos_nm: [
                i32::from_le_bytes(*x),
                i32::from_le_bytes(*y),
                i32::from_le_bytes(*z),
            ],
            feed_um_s: u32::from_le_bytes(*feed),
        })
    }
}

/// Sends each setpoint as one [`Frame`] in one [`SpiDevice::write`].
#[derive(Debug)]
pub struct SpiSetpointSink<SPI> {
    spi: SPI,
    seq: u16,
}

impl<SPI> SpiSetpointSink<SPI> {
    /// A sink whose first frame has sequence number 0.
    pub fn new(spi: SPI) -> Self {
        Self::with_seq(spi, 0)
    }

    /// A sink whose first frame has sequence number `seq`.
    pub fn with_seq(spi: SPI, seq: u16) -> Self {
        SpiSetpointSink { spi, seq }
    }

    /// The sequence number of the next frame.
    pub fn next_seq(&self) -> u16 {
        self.seq
    }

    /// The SPI device back.
    pub fn release(self) -> SPI {
        self.spi
    }
}

impl<SPI: SpiDevice> SetpointSink for SpiSetpointSink<SPI> {
    type Error = SpiSinkError<SPI::Error>;

    fn put(&mut self, sp: &Setpoint) -> Result<(), Self::Error> {
        let frame = Frame::from_setpoint(self.seq, sp).map_err(SpiSinkError::widen)?;
        self.spi.write(&frame.to_bytes()).map_err(SpiSinkError::Spi)?;
        self.seq = self.seq.wrapping_add(1);
        Ok(())
    }
}

/// Why [`StrobeSink`] failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StrobeError<S, P> {
    /// The inner sink refused the setpoint (the pin was not touched).
    Sink(S),
    /// The setpoint was delivered but the pin could not be driven.
    Pin(P),
}

/// Delivers each setpoint to `inner`, then toggles `pin`: one edge per
/// delivered setpoint (rising, falling, rising, …; the pin is assumed low at
/// the start and is not driven by [`StrobeSink::new`]).
#[derive(Debug)]
pub struct StrobeSink<S, P> {
    inner: S,
    pin: P,
    level: PinState,
}

impl<S, P> StrobeSink<S, P> {
    /// Pair `inner` with the strobe `pin` (low).
    pub fn new(inner: S, pin: P) -> Self {
        StrobeSink {
            inner,
            pin,
            level: PinState::Low,
        }
    }

    /// The inner sink.
    pub fn inner(&self) -> &S {
        &self.inner
    }

    /// The inner sink and the pin back.
    pub fn release(self) -> (S, P) {
        (self.inner, self.pin)
    }
}

impl<S: SetpointSink, P: OutputPin> SetpointSink for StrobeSink<S, P> {
    type Error = StrobeError<S::Error, P::Error>;

    fn put(&mut self, sp: &Setpoint) -> Result<(), Self::Error> {
        self.inner.put(sp).map_err(StrobeError::Sink)?;
        let next = !self.level;
        self.pin.set_state(next).map_err(StrobeError::Pin)?;
        self.level = next;
        Ok(())
    }
}

// With defmt: the errors are `defmt::Format` for embedded-hal's own error kinds.
#[cfg(feature = "defmt")]
const _: fn() = || {
    fn format<T: defmt::Format>() {}
    format::<Frame>();
    format::<SpiSinkError<embedded_hal::spi::ErrorKind>>();
    format::<StrobeError<SpiSinkError<embedded_hal::spi::ErrorKind>, embedded_hal::digital::ErrorKind>>();
};

#[cfg(test)]
pub(crate) mod tests {
    use std::vec;
    use std::vec::Vec;

    use embedded_hal::digital::{self, PinState};
    use embedded_hal::spi::{self, ErrorKind, Operation, SpiDevice};

    use super::*;

    /// Records every transaction's written bytes; fails while `fail` is set.
    #[derive(Debug, Default)]
    pub(crate) struct FakeSpi {
        pub(crate) frames: Vec<Vec<u8>>,
        pub(crate) fail: bool,
    }

    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub(crate) struct FakeError;

    impl spi::Error for FakeError {
        fn kind(&self) -> ErrorKind {
            ErrorKind::Other
        }
    }

    impl spi::ErrorType for FakeSpi {
        type Error = FakeError;
    }

    impl SpiDevice for FakeSpi {
        fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), FakeError> {
            if self.fail {
                return Err(FakeError);
            }
            let mut bytes = Vec::new();
            for op in ops {
                match op {
                    Operation::Write(w) => bytes.extend_from_slice(w),
                    // the sink only writes
                    _ => return Err(FakeError),
                }
            }
            self.frames.push(bytes);
            Ok(())
        }
    }

    /// Records the levels driven; fails while `fail` is set.
    #[derive(Debug, Default)]
    struct FakePin {
        levels: Vec<PinState>,
        fail: bool,
    }

    impl digital::ErrorType for FakePin {
        type Error = digital::ErrorKind;
    }

    impl OutputPin for FakePin {
        fn set_low(&mut self) -> Result<(), Self::Error> {
            self.set_state(PinState::Low)
        }
        fn set_high(&mut self) -> Result<(), Self::Error> {
            self.set_state(PinState::High)
        }
        fn set_state(&mut self, s: PinState) -> Result<(), Self::Error> {
            if self.fail {
                return Err(digital::ErrorKind::Other);
            }
            self.levels.push(s);
            Ok(())
        }
    }

    fn sp(pos_mm: [f64; 3], feed_mm_s: f64) -> Setpoint {
        Setpoint {
            t_s: 0.25,
            s_mm: 3.0,
            u: 0.5,
            feed_mm_s,
            pos_mm,
        }
    }

    fn le_i32(b: &[u8], at: usize) -> i32 {
        i32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }

    #[test]
    fn crc_is_ccitt_false() {
        assert_eq!(FRAME_CRC.checksum(b"123456789"), 0x29B1);
    }

    #[test]
    fn frame_bytes_of_a_known_setpoint() {
        let mut sink = SpiSetpointSink::with_seq(FakeSpi::default(), 0x1234);
        // nm rounding: .4 down, .6 up (away from 0 for negatives), tiny → 0
        sink.put(&sp([1.000_000_4, -2.500_000_6, 0.000_000_4], 123.456_7))
            .unwrap();
        let spi = sink.release();
        assert_eq!(spi.frames.len(), 1);
        let b = &spi.frames[0];
        assert_eq!(b.len(), FRAME_LEN);
        assert_eq!(&b[0..2], &[0x34, 0x12]);
        assert_eq!(le_i32(b, 2), 1_000_000);
        assert_eq!(le_i32(b, 6), -2_500_001);
        assert_eq!(le_i32(b, 10), 0);
        assert_eq!(u32::from_le_bytes(b[14..18].try_into().unwrap()), 123_457);
        // the body bytes, by hand
        let mut body = vec![0x34, 0x12];
        body.extend_from_slice(&[0x40, 0x42, 0x0F, 0x00]); // 1_000_000
        body.extend_from_slice(&(-2_500_001i32).to_le_bytes());
        body.extend_from_slice(&[0, 0, 0, 0]);
        body.extend_from_slice(&[0x41, 0xE2, 0x01, 0x00]); // 123_457
        assert_eq!(&b[..FRAME_BODY_LEN], &body[..]);
        // CRC over bytes 0..18, little-endian at 18..20
        let crc = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740).checksum(&body);
        assert_eq!(&b[FRAME_BODY_LEN..], &crc.to_le_bytes());
        let bytes: [u8; FRAME_LEN] = b[..].try_into().unwrap();
        assert_eq!(
            Frame::from_bytes(&bytes),
            Some(Frame {
                seq: 0x1234,
                pos_nm: [1_000_000, -2_500_001, 0],
                feed_um_s: 123_457,
            })
        );
    }

    #[test]
    fn every_flipped_bit_fails_the_crc() {
        let bytes = Frame::from_setpoint(9, &sp([12.5, -0.75, 300.0], 80.0))
            .unwrap()
            .to_bytes();
        assert!(Frame::from_bytes(&bytes).is_some());
        for bit in 0..FRAME_LEN * 8 {
            let mut b = bytes;
            b[bit / 8] ^= 1 << (bit % 8);
            assert_eq!(Frame::from_bytes(&b), None, "bit {bit}");
        }
    }

    #[test]
    fn sequence_wraps_at_u16_max() {
        let mut sink = SpiSetpointSink::with_seq(FakeSpi::default(), u16::MAX - 1);
        for _ in 0..3 {
            sink.put(&sp([0.0; 3], 0.0)).unwrap();
        }
        assert_eq!(sink.next_seq(), 1);
        let seqs: Vec<u16> = sink
            .release()
            .frames
            .iter()
            .map(|f| Frame::from_bytes(&f[..].try_into().unwrap()).unwrap().seq)
            .collect();
        assert_eq!(seqs, [u16::MAX - 1, u16::MAX, 0]);
    }

    #[test]
    fn range_limits_and_out_of_range() {
        let max = f64::from(i32::MAX) / 1e6; // 2147.483647 mm
        let min = f64::from(i32::MIN) / 1e6;
        let f = Frame::from_setpoint(0, &sp([max, min, -0.0], 0.0)).unwrap();
        assert_eq!(f.pos_nm, [i32::MAX, i32::MIN, 0]);
        let f = Frame::from_setpoint(0, &sp([0.0; 3], f64::from(u32::MAX) / 1e3)).unwrap();
        assert_eq!(f.feed_um_s, u32::MAX);

        let mut sink = SpiSetpointSink::new(FakeSpi::default());
        let cases = [
            ([max + 1e-6, 0.0, 0.0], 1.0, SpiSinkError::OutOfRange { axis: 0 }),
            ([0.0, min - 1e-6, 0.0], 1.0, SpiSinkError::OutOfRange { axis: 1 }),
            ([0.0, 0.0, f64::NAN], 1.0, SpiSinkError::OutOfRange { axis: 2 }),
            (
                [0.0, f64::INFINITY, f64::NAN],
                1.0,
                SpiSinkError::OutOfRange { axis: 1 },
            ),
            ([0.0, 0.0, -1e300], 1.0, SpiSinkError::OutOfRange { axis: 2 }),
            ([0.0; 3], -0.001, SpiSinkError::FeedOutOfRange),
            ([0.0; 3], f64::NAN, SpiSinkError::FeedOutOfRange),
            ([0.0; 3], 5e6, SpiSinkError::FeedOutOfRange),
        ];
        for (pos, feed, want) in cases {
            assert_eq!(sink.put(&sp(pos, feed)), Err(want), "{pos:?} {feed}");
        }
        // nothing sent, the number did not move
        assert_eq!(sink.next_seq(), 0);
        assert!(sink.release().frames.is_empty());
    }

    #[test]
    fn spi_error_propagated_and_retry_keeps_the_number() {
        let mut sink = SpiSetpointSink::with_seq(
            FakeSpi {
                fail: true,
                ..FakeSpi::default()
            },
            41,
        );
        let p = sp([1.0, 2.0, 3.0], 10.0);
        assert_eq!(sink.put(&p), Err(SpiSinkError::Spi(FakeError)));
        assert_eq!(sink.next_seq(), 41);
        sink.spi.fail = false;
        sink.put(&p).unwrap();
        let spi = sink.release();
        assert_eq!(spi.frames.len(), 1);
        let f = Frame::from_bytes(&spi.frames[0][..].try_into().unwrap()).unwrap();
        assert_eq!(f.seq, 41);
        assert_eq!(f.pos_nm, [1_000_000, 2_000_000, 3_000_000]);
    }

    #[test]
    fn strobe_toggles_once_per_delivered_setpoint() {
        let mut s = StrobeSink::new(SpiSetpointSink::new(FakeSpi::default()), FakePin::default());
        for _ in 0..3 {
            s.put(&sp([0.0; 3], 1.0)).unwrap();
        }
        // a refused setpoint: no edge
        assert_eq!(
            s.put(&sp([f64::NAN; 3], 1.0)),
            Err(StrobeError::Sink(SpiSinkError::OutOfRange { axis: 0 }))
        );
        let (spi, mut pin) = s.release();
        assert_eq!(spi.release().frames.len(), 3);
        assert_eq!(pin.levels, [PinState::High, PinState::Low, PinState::High]);
        // pin failure after delivery
        pin.fail = true;
        let mut s = StrobeSink::new(heapless::Vec::<Setpoint, 4>::new(), pin);
        let r = s.put(&sp([0.0; 3], 1.0));
        assert_eq!(r, Err(StrobeError::Pin(digital::ErrorKind::Other)));
        assert_eq!(s.inner().len(), 1);
    }
}
