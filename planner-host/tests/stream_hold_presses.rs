//! A starved stop pressed where the firmware presses it: at its own first
//! tick at or past the last chunk's hold point s_c, anywhere within a
//! tick's step of it (after a starvation its ticks no longer fall on the
//! dry run's), and from a resume's control period a tick later. The
//! stop's length can differ by millimetres from one tick's press to the
//! next (its look-ahead is refreshed in sweeps, and which sweep first
//! leaves a stretch of high acceleration behind turns on the press), so
//! the search presses each hold point's hold on the ticks after it as
//! well (`HoldSearch::press_ticks`). Run at a servo period a little off
//! the search's, the presses fall between the dry run's ticks: every one
//! within two ticks of each hold point still rests inside its rows.
//! Pressed at s_c alone, a press of this kind ran past its rows on the
//! Butterfly in 8 mm chunks and the Fan in 4 mm chunks through a 128:256
//! window (measured: `examples/hold_press_spread.rs`).

use crate::support;

use firmware_core::Table;
use planner_host::stream_hold::{on_big_stack, presses_near_hold_points, set_hold_points, HoldSearch};

const Q: usize = 128;
const P: usize = 256;

fn presses_rest_inside(name: &str, chunk_mm: f64) {
    let (bytes, mut chunks) = support::in_chunks(name, chunk_mm);
    let table = Table::parse(&bytes).unwrap();
    let how = HoldSearch::default();
    assert!(how.press_ticks >= 3);
    let hp = set_hold_points::<Q, P>(&table, &mut chunks, &how).unwrap();
    for period_s in [250.0001e-6, 249.9999e-6] {
        let near = presses_near_hold_points::<Q, P>(&table, &chunks, &hp.s_c_mm, period_s, 2).unwrap();
        assert!(near.len() >= 20, "{name}: {} hold points", near.len());
        let mut least = f64::INFINITY;
        for n in &near {
            assert_eq!(n.presses.len(), 2, "{name}: chunk {}", n.chunk);
            for &(press, rest) in &n.presses {
                // within a tick's step (under 0.05 mm at full feed) past s_c
                assert!(
                    press - hp.s_c_mm[n.chunk] < 0.1,
                    "{name}: chunk {} pressed at {press}",
                    n.chunk
                );
                assert!(
                    rest < n.end_mm,
                    "{name}, ticks of {period_s} s: chunk {} pressed at {press} mm rested at {rest} mm, its rows end at {} mm",
                    n.chunk,
                    n.end_mm
                );
                least = least.min(n.end_mm - rest);
            }
        }
        println!(
            "{name} in {chunk_mm} mm chunks, ticks of {period_s} s: {} hold points, least room {least:.3} mm",
            near.len()
        );
    }
}

#[test]
fn holds_pressed_between_the_dry_runs_ticks_rest_inside_the_rows() {
    on_big_stack(|| {
        presses_rest_inside("butterfly", 8.0);
        presses_rest_inside("fan", 4.0);
    })
    .unwrap();
}
