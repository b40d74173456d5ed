//! The host side of a streamed run over a serial byte stream: plans a curve,
//! cuts the plan into chunks and sends them framed (HEAD, then DATA) to a
//! firmware over a pipe pair — QEMU's `-chardev pipe` (`PATH.in` is what the
//! firmware's UART receives, `PATH.out` what it sends) — within the credits
//! its ACKs grant (the ring's free bytes, less what was sent since), resending
//! from a NAK's seq. The ACKs are taken `--latency-ms` after they arrive and
//! the frames leave as late, so the credits are as old as over a link with
//! that one-way latency.
//!
//! `STREAM_SEND_DEBUG=1` prints every ACK as it is taken.
//!
//! `--windows W:C` plans the curve in windows of W mm committing C mm and
//! sends while it plans: the head (its stop segment not yet known) once the
//! first window has committed, each chunk as soon as it is final, and the
//! head again with the stop segment when the last window has it (the
//! firmware waits for it before the last rows). Without it the whole path
//! is planned first.
//!
//! `--faults corrupt:N,drop:N,duplicate:N,reorder:N,restart:N` makes the
//! link lose frames: every Nth DATA frame sent (counted over every
//! transmission, resends included) has a bit flipped, is not sent, is sent
//! twice, or is held back and sent after the next; and after the Nth the
//! host restarts once (it forgets what it sent and what came back, sends
//! the head and the chunks from the first again, with the ring's whole
//! size as its credit: the firmware ACKs each chunk it has already, and the
//! host goes on after the last it ACKed). The firmware must refuse what is
//! wrong, NAK the seq it expects and run the same setpoints; a frame lost
//! with nothing after it to show the gap is sent again once the firmware
//! has been quiet for two round trips and 3 s with chunks
//! unacknowledged.
//!
//! `--u-form` sends the chunks with the u form (each piece's u(s)), so that
//! the setpoints report u; without it (the default) their u reads 0 along
//! the path, and their positions (and the digest) are the same.
//!
//! `--cruise-density C` (default 0.125, as `feedsim stream`) samples the
//! plan at C points per mm where it cruises at the feed limit
//! (`PlanConfig::cruise_density_per_mm`).
//!
//! `--digest` prints the host's own streamed run's digest at the end (the same
//! chunks through `PlanWindow` and the streamed interpolator, FNV-1a over
//! the setpoints' positions, as the firmware prints it): `.ci/qemu-uart-stream.sh`
//! compares the two.
//!
//! ```text
//! cargo run --release -p planner-host --example stream_send -- CURVE --pipe PATH
//!     [--chunk-mm 8] [--ring-bytes 16384] [--latency-ms 50] [--windows W:C]
//!     [--faults corrupt:N,drop:N,duplicate:N,reorder:N,restart:N] [--u-form]
//!     [--cruise-density C] [--digest]
//! ```

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use firmware_core::digest::Fnv1a64;
use firmware_core::stream::frame::{encode_data, encode_head, encoded_max_len};
use firmware_core::stream::{Frame, FrameDecoder, StreamHead};
use firmware_core::Table;
use planner_host::plan::{plan_curve, PlanConfig, PlanOutput, WindowConfig};
use planner_host::stream::{chunk_table, ChunkOptions};
use planner_host::stream_hold::{stream_head, StreamedRun};
use planner_host::stream_pipeline::{plan_in_chunks, Planned as InChunks};
use std::sync::Mutex;

/// The host's window for its own run (any size that holds a chunk or two
/// gives the same setpoints).
const NQ: usize = 64;
const NP: usize = 128;

struct Args {
    curve: String,
    pipe: String,
    chunk_mm: f64,
    ring_bytes: usize,
    latency: Duration,
    digest: bool,
    /// Plan in windows (window, commit mm) and send while planning.
    windows: Option<(f64, f64)>,
    faults: Faults,
    /// The chunks carry the u form.
    u_form: bool,
    /// Points per mm where the plan cruises (`PlanConfig::cruise_density_per_mm`).
    cruise: f64,
}

/// Every this many DATA transmissions a frame is lost so (0: never).
#[derive(Clone, Copy, Default)]
struct Faults {
    corrupt: usize,
    drop: usize,
    duplicate: usize,
    reorder: usize,
    restart: usize,
}

impl Faults {
    fn parse(v: &str) -> Result<Self, String> {
        let mut f = Faults::default();
        for part in v.split(',').filter(|p| !p.is_empty()) {
            let (k, n) = part.split_once(':').ok_or(format!("--faults: {part}: KIND:N"))?;
            let n: usize = n.parse().map_err(|e| format!("--faults: {part}: {e}"))?;
            match k {
                "corrupt" => f.corrupt = n,
                "drop" => f.drop = n,
                "duplicate" => f.duplicate = n,
                "reorder" => f.reorder = n,
                "restart" => f.restart = n,
                _ => {
                    return Err(format!(
                        "--faults: {k}: not corrupt, drop, duplicate, reorder or restart"
                    ))
                }
            }
        }
        Ok(f)
    }

    /// Whether the `tx`th transmission (from 1) is lost by the fault of period `n`.
    fn hits(n: usize, tx: usize) -> bool {
        n > 0 && tx.is_multiple_of(n)
    }
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        curve: String::new(),
        pipe: String::new(),
        chunk_mm: 8.0,
        ring_bytes: 16384,
        latency: Duration::from_millis(50),
        digest: false,
        windows: None,
        faults: Faults::default(),
        u_form: false,
        cruise: 0.125,
    };
    let mut it = std::env::args().skip(1);
    while let Some(x) = it.next() {
        let mut val = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match x.as_str() {
            "--pipe" => a.pipe = val("--pipe")?,
            "--chunk-mm" => {
                a.chunk_mm = val("--chunk-mm")?
                    .parse()
                    .map_err(|e| format!("--chunk-mm: {e}"))?
            }
            "--ring-bytes" => {
                a.ring_bytes = val("--ring-bytes")?
                    .parse()
                    .map_err(|e| format!("--ring-bytes: {e}"))?
            }
            "--latency-ms" => {
                let ms: f64 = val("--latency-ms")?
                    .parse()
                    .map_err(|e| format!("--latency-ms: {e}"))?;
                a.latency = Duration::from_secs_f64(ms.max(0.0) * 1e-3);
            }
            "--digest" => a.digest = true,
            "--u-form" => a.u_form = true,
            "--cruise-density" => {
                a.cruise = val("--cruise-density")?
                    .parse()
                    .map_err(|e| format!("--cruise-density: {e}"))?;
                if !(a.cruise.is_finite() && a.cruise > 0.0) {
                    return Err(format!("--cruise-density {}: must be a number > 0", a.cruise));
                }
            }
            "--windows" => {
                let v = val("--windows")?;
                let (w, c) = v.split_once(':').ok_or("--windows WINDOW_MM:COMMIT_MM")?;
                a.windows = Some((
                    w.parse().map_err(|e| format!("--windows: {e}"))?,
                    c.parse().map_err(|e| format!("--windows: {e}"))?,
                ));
            }
            "--faults" => a.faults = Faults::parse(&val("--faults")?)?,
            _ if a.curve.is_empty() => a.curve = x,
            _ => return Err(format!("unexpected argument {x}")),
        }
    }
    if a.curve.is_empty() || a.pipe.is_empty() {
        return Err("usage: stream_send CURVE --pipe PATH [--chunk-mm 8] [--ring-bytes 16384] [--latency-ms 50] [--windows W:C] [--faults corrupt:N,drop:N,duplicate:N,reorder:N,restart:N] [--u-form] [--digest]".into());
    }
    Ok(a)
}

/// The host's streamed run: the digest of its setpoints and the ticks.
fn host_digest(table: &Table, chunks: &[Vec<u8>]) -> Result<(u64, u64), String> {
    let mut run = StreamedRun::<NQ, NP>::start(table, chunks, 250e-6).map_err(|e| e.to_string())?;
    let mut d = Fnv1a64::new();
    while !run.ip.is_done() {
        d.setpoint(&run.step(chunks).map_err(|e| e.to_string())?);
    }
    Ok((d.finish(), run.ip.ticks()))
}

fn main() {
    if let Err(e) = run() {
        eprintln!("stream_send: {e}");
        std::process::exit(1);
    }
}

/// What the planning side hands the sender, in order.
enum Planned {
    /// The stream head; whether its stop segment is known.
    Head(StreamHead, bool),
    /// The head again, its stop segment known.
    Stop(StreamHead),
    /// Chunks that became final.
    Chunks(Vec<Vec<u8>>),
    /// The plan is finished.
    Done(Box<Result<PlanOutput, String>>),
}

/// Plan `curve` whole and hand everything over at once.
fn plan_whole(
    curve: &planner_host::Nurbs,
    cfg: &PlanConfig,
    opts: &ChunkOptions,
    to: &mpsc::Sender<Planned>,
) -> Result<(), String> {
    let out = plan_curve(curve, cfg).map_err(|e| e.to_string())?;
    let table = Table::parse(&out.table_bytes).map_err(|e| e.to_string())?;
    let chunks = chunk_table(&table, opts).map_err(|e| e.to_string())?;
    let head = stream_head(&table).ok_or("no stream head")?;
    let _ = to.send(Planned::Head(head, true));
    let _ = to.send(Planned::Chunks(chunks));
    let _ = to.send(Planned::Done(Box::new(Ok(out))));
    Ok(())
}

/// Plan `curve` window by window, handing over the head after the first
/// commit, each chunk as it becomes final and the stop with the last
/// (`stream_pipeline::plan_in_chunks`).
fn plan_windows(
    curve: &planner_host::Nurbs,
    base: &PlanConfig,
    (window_mm, commit_mm): (f64, f64),
    opts: &ChunkOptions,
    to: &mpsc::Sender<Planned>,
) {
    let cfg = PlanConfig {
        windows: Some(WindowConfig::new(window_mm, commit_mm)),
        ..base.clone()
    };
    let to_m = Mutex::new(to.clone());
    let r = plan_in_chunks(curve, &cfg, opts, &|m| {
        let m = match m {
            InChunks::Head(h) => Planned::Head(h, false),
            InChunks::Chunks(c) => Planned::Chunks(c),
            InChunks::Stop(h) => Planned::Stop(h),
        };
        let _ = to_m.lock().unwrap_or_else(|e| e.into_inner()).send(m);
    })
    .map_err(|e| e.to_string());
    let _ = to.send(Planned::Done(Box::new(r)));
}

fn run() -> Result<(), String> {
    let a = args()?;
    let curve = planner_host::cli::load_curve(std::path::Path::new(&a.curve)).map_err(|e| e.to_string())?;
    let opts = ChunkOptions {
        chunk_mm: a.chunk_mm,
        u_form: a.u_form,
        max_chunk_bytes: Some(a.ring_bytes / 4),
        ..ChunkOptions::default()
    };
    let started = Instant::now();
    let (plan_tx, planned) = mpsc::channel::<Planned>();
    {
        let (curve, windows) = (curve.clone(), a.windows);
        let cfg = PlanConfig {
            cruise_density_per_mm: Some(a.cruise),
            ..PlanConfig::default()
        };
        std::thread::spawn(move || match windows {
            Some(w) => plan_windows(&curve, &cfg, w, &opts, &plan_tx),
            None => {
                if let Err(e) = plan_whole(&curve, &cfg, &opts, &plan_tx) {
                    let _ = plan_tx.send(Planned::Done(Box::new(Err(e))));
                }
            }
        });
    }
    let mut tx = std::fs::OpenOptions::new()
        .write(true)
        .open(format!("{}.in", a.pipe))
        .map_err(|e| format!("{}.in: {e}", a.pipe))?;
    let mut rx =
        std::fs::File::open(format!("{}.out", a.pipe)).map_err(|e| format!("{}.out: {e}", a.pipe))?;
    // The firmware's ACKs and NAKs, decoded on a thread, each stamped when it came.
    let (up_tx, up) = mpsc::channel::<(Instant, Up)>();
    std::thread::spawn(move || {
        let mut dec: FrameDecoder<64> = FrameDecoder::new();
        let mut buf = [0u8; 256];
        while let Ok(n) = rx.read(&mut buf) {
            if n == 0 {
                return;
            }
            for &b in &buf[..n] {
                let msg = match dec.feed(b) {
                    Some(Ok(Frame::Ack { seq, free })) => Up::Ack { seq, free },
                    Some(Ok(Frame::Nak { expected })) => Up::Nak { expected },
                    _ => continue,
                };
                if up_tx.send((Instant::now(), msg)).is_err() {
                    return;
                }
            }
        }
    });
    // ACKs are taken a round trip (2 × the one-way latency) after they came.
    let rtt = 2 * a.latency;
    let mut waiting: VecDeque<(Instant, Up)> = VecDeque::new();
    let mut frame = vec![0u8; encoded_max_len(a.ring_bytes + 1)];
    let (mut next, mut acked, mut free) = (0usize, None::<usize>, None::<usize>);
    let (mut sent_frames, mut sent_bytes, mut resends) = (0usize, 0usize, 0usize);
    // (a frame held back by a reorder, sent after the next one)
    let mut held_back: Option<Vec<u8>> = None;
    let (mut lost, mut restarts) = (0usize, 0usize);
    // the last rewind to a NAK's seq: when, and to which
    let mut rewound: Option<(Instant, usize)> = None;
    // chunks unacknowledged and the firmware quiet this long: resend (the
    // firmware under QEMU takes its UART's bytes one per pass of its loop,
    // a tick between: measured, a second and more without a word)
    let resend_after = 2 * rtt + Duration::from_secs(3);
    let mut quiet_since = Instant::now();
    // what planning handed over so far
    let mut chunks: Vec<Vec<u8>> = Vec::new();
    let (mut head, mut head_sent, mut stop) = (None::<(StreamHead, bool)>, false, None::<StreamHead>);
    let mut plan: Option<PlanOutput> = None;
    let mut first_chunk_s = None::<f64>;
    let mut all_cut = false;
    while !(all_cut && matches!(acked, Some(k) if k + 1 >= chunks.len())) {
        while let Ok(p) = planned.try_recv() {
            match p {
                Planned::Head(h, known) => head = Some((h, known)),
                Planned::Stop(h) => stop = Some(h),
                Planned::Chunks(c) => {
                    first_chunk_s.get_or_insert(started.elapsed().as_secs_f64());
                    all_cut |= c.last().is_some_and(|b| {
                        firmware_core::stream::Chunk::parse(b).is_ok_and(|c| c.info().is_last())
                    });
                    chunks.extend(c);
                }
                Planned::Done(r) => plan = Some((*r)?),
            }
        }
        // the head once the firmware has spoken, then the stop when known
        // (before any chunk handed over after it)
        if let (false, Some(_), Some((h, known))) = (head_sent, free, head) {
            let k = encode_head(&h, 1, known, &mut frame).map_err(|e| format!("{e:?}"))?;
            tx.write_all(&frame[..k]).map_err(|e| e.to_string())?;
            head_sent = true;
            if known {
                stop = None;
            }
        }
        if let (true, Some(h)) = (head_sent, stop.take()) {
            let k = encode_head(&h, 1, true, &mut frame).map_err(|e| format!("{e:?}"))?;
            tx.write_all(&frame[..k]).map_err(|e| e.to_string())?;
        }
        let n = chunks.len();
        while let Ok(m) = up.try_recv() {
            waiting.push_back(m);
        }
        let now = Instant::now();
        while waiting
            .front()
            .is_some_and(|(at, _)| now.duration_since(*at) >= rtt)
        {
            let Some((came, m)) = waiting.pop_front() else {
                break;
            };
            quiet_since = now;
            match m {
                Up::Ack { seq, free: f } => {
                    if std::env::var_os("STREAM_SEND_DEBUG").is_some() {
                        eprintln!("ack {seq} free {f} (next {next})");
                    }
                    free = Some(f as usize);
                    if seq != u32::MAX {
                        // (the firmware has every chunk through seq: after
                        // a NAK's rewind, those need not go again)
                        acked = Some(seq as usize);
                        next = next.max(seq as usize + 1);
                    }
                }
                Up::Nak { expected } => {
                    let e = expected as usize;
                    // (every frame after a gap is NAKed: those that came
                    // before the last rewind, from its seq on, are answered)
                    let answered = rewound.is_some_and(|(at, to)| came <= at && e >= to);
                    if !answered {
                        // (the firmware has every chunk before e: back to
                        // it, or on to it after a restart)
                        resends += next.saturating_sub(e);
                        next = e;
                        acked = e.checked_sub(1);
                        rewound = Some((now, e));
                    }
                }
            }
        }
        let pending: usize = chunks[acked.map_or(0, |k| k + 1)..next]
            .iter()
            .map(Vec::len)
            .sum();
        if a.faults.restart > 0 && sent_frames == a.faults.restart && restarts == 0 {
            // (a restarted host: it planned the same chunks again)
            restarts += 1;
            (next, acked, free, head_sent) = (0, None, Some(a.ring_bytes), false);
            (rewound, held_back) = (None, None);
            waiting.clear();
            while up.try_recv().is_ok() {}
            quiet_since = Instant::now();
            continue;
        }
        let first_unacked = acked.map_or(0, |k| k + 1);
        if next > first_unacked && quiet_since.elapsed() > resend_after {
            resends += next - first_unacked;
            next = first_unacked;
            quiet_since = Instant::now();
            rewound = Some((quiet_since, next));
        }
        match free {
            Some(f) if head_sent && next < n && f.saturating_sub(pending) >= chunks[next].len() => {
                let k = encode_data(&chunks[next], &mut frame).map_err(|e| format!("{e:?}"))?;
                sent_frames += 1;
                sent_bytes += k;
                next += 1;
                let bytes = &mut frame[..k];
                let fl = a.faults;
                if Faults::hits(fl.corrupt, sent_frames) {
                    // (a bit of the body: the frame's CRC fails)
                    bytes[k / 2] ^= 0x10;
                }
                if Faults::hits(fl.drop, sent_frames) {
                    lost += 1;
                    continue;
                }
                if Faults::hits(fl.reorder, sent_frames) && held_back.is_none() {
                    held_back = Some(bytes.to_vec());
                    continue;
                }
                tx.write_all(bytes).map_err(|e| e.to_string())?;
                if Faults::hits(fl.duplicate, sent_frames) {
                    tx.write_all(bytes).map_err(|e| e.to_string())?;
                }
                if let Some(b) = held_back.take() {
                    tx.write_all(&b).map_err(|e| e.to_string())?;
                }
            }
            _ => {
                // (a frame held back with none to follow goes now)
                if let Some(b) = held_back.take() {
                    tx.write_all(&b).map_err(|e| e.to_string())?;
                }
                std::thread::sleep(Duration::from_micros(200))
            }
        }
        if quiet_since.elapsed() > Duration::from_secs(120) {
            return Err(format!(
                "no word from the firmware for 120 s ({next} of {n} chunks sent)"
            ));
        }
    }
    println!(
        "sent {sent_frames} DATA frames ({sent_bytes} bytes, {resends} resent, {lost} lost on the way, {restarts} host restarts) in {:.2} s with {} ms one-way latency, the first chunk ready after {:.1} ms",
        started.elapsed().as_secs_f64(),
        a.latency.as_millis(),
        first_chunk_s.unwrap_or(f64::NAN) * 1e3
    );
    // the plan is finished by the time its last chunk is acknowledged
    while plan.is_none() {
        match planned.recv() {
            Ok(Planned::Done(r)) => plan = Some((*r)?),
            Ok(_) => {}
            Err(_) => return Err("planning ended without a plan".into()),
        }
    }
    let out = plan.ok_or("no plan")?;
    let table = Table::parse(&out.table_bytes).map_err(|e| e.to_string())?;
    let framed: usize = chunks.iter().map(|c| encoded_max_len(c.len() + 1)).sum();
    println!(
        "{}: L {:.2} mm, table {} bytes, {} chunks, {} bytes framed ({:.1} B/mm), planned in {:.2} s{}",
        a.curve,
        table.path_length_mm(),
        out.table_bytes.len(),
        chunks.len(),
        framed,
        framed as f64 / table.path_length_mm(),
        out.total_time_s,
        if a.windows.is_some() {
            " while sending"
        } else {
            " before sending"
        }
    );
    if a.digest {
        let (d, ticks) = host_digest(&table, &chunks)?;
        println!("host streamed run: {ticks} ticks, digest: fnv1a64-pos-le={d:016x}");
    }
    Ok(())
}

/// What the firmware sends up.
enum Up {
    Ack { seq: u32, free: u32 },
    Nak { expected: u32 },
}
