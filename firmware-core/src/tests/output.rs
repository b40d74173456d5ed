//! Setpoints through the embedded-hal SPI frame sink.

use std::vec::Vec;

use super::fixtures::*;

#[test]
fn run_through_the_spi_frame_sink() {
    use crate::output::hal::tests::FakeSpi;
    use crate::output::hal::{Frame, SpiSetpointSink};

    let bytes = good().encode().unwrap();
    let mut ip = Interpolator::new(Table::parse(&bytes).unwrap(), 1e-3).unwrap();
    let reference = run_all(&mut ip.clone());
    let mut sink = SpiSetpointSink::new(FakeSpi::default());
    let n = ip.run(&mut sink).unwrap();
    let frames: Vec<Frame> = sink
        .release()
        .frames
        .iter()
        .map(|b| Frame::from_bytes(&b[..].try_into().unwrap()).expect("CRC"))
        .collect();
    assert_eq!(frames.len() as u64, n);
    assert_eq!(frames.len(), reference.len());
    for (k, (f, sp)) in frames.iter().zip(&reference).enumerate() {
        assert_eq!(usize::from(f.seq), k % 65536);
        for (nm, mm) in f.pos_nm.iter().zip(sp.pos_mm) {
            assert!((f64::from(*nm) - mm * 1e6).abs() <= 0.5, "tick {k}");
        }
        assert!(
            (f64::from(f.feed_um_s) - sp.feed_mm_s * 1e3).abs() <= 0.5,
            "tick {k}"
        );
    }
    let last = frames.last().unwrap();
    assert_eq!((last.pos_nm, last.feed_um_s), ([100_000_000, 0, 0], 0));
}
