//! Step and direction output over whole paths (the Butterfly and the Fan,
//! planned with Table 1 at 250 µs): after every servo period each axis's step
//! count equals round(position × steps/mm) of that tick's setpoint, and no
//! two steps of an axis, in a period or across a period boundary, are closer
//! than the drive's step rate and pulse width allow. A rate too low for the
//! plan is refused with a typed error and nothing emitted.

use firmware_core::output::step_dir::{
    StepConfig, StepDirSink, StepError, StepGen, StepOutput, StepPeriod, StepSinkError, AXES,
};
use firmware_core::output::SetpointSink;
use firmware_core::{Interpolator, Setpoint, Table};
use planner_host::builtin;
use planner_host::plan::{self, PlanConfig};

const PERIOD_NS: u32 = 250_000;

fn setpoints(name: &str) -> Vec<Setpoint> {
    let curve = builtin::by_name(name).unwrap().unwrap();
    let out = plan::plan_curve(&curve, &PlanConfig::default()).unwrap();
    let table = Table::parse(&out.table_bytes).unwrap();
    let mut it = Interpolator::new(table, f64::from(PERIOD_NS) * 1e-9).unwrap();
    let mut v = Vec::new();
    while !it.is_done() {
        v.push(it.tick().unwrap());
    }
    v
}

/// Every step's rising edge, per axis, on one clock (ns), and the position
/// in steps after each period.
#[derive(Default)]
struct Recorder {
    edges: [Vec<u64>; AXES],
    signed: [i64; AXES],
    after: Vec<[i64; AXES]>,
    periods: u64,
}

impl StepOutput for Recorder {
    type Error = core::convert::Infallible;
    fn emit(&mut self, p: &StepPeriod) -> Result<(), Self::Error> {
        let t0 = self.periods * u64::from(p.period_ns);
        for (axis, a) in p.axes.iter().enumerate() {
            for k in 0..a.count {
                let t = a.edge_ns(k);
                assert!(t < p.period_ns, "a step past its period");
                self.edges[axis].push(t0 + u64::from(t));
            }
            let n = i64::from(a.count);
            self.signed[axis] += if a.forward { n } else { -n };
        }
        self.after.push(self.signed);
        self.periods += 1;
        Ok(())
    }
}

fn config(steps_per_mm: f64, max_step_hz: f64) -> StepConfig {
    StepConfig {
        steps_per_mm: [steps_per_mm; AXES],
        max_step_hz,
        step_len_ns: 2_000,
        step_space_ns: 2_000,
        dir_setup_ns: 5_000,
        invert_dir: [false, true, false],
    }
}

#[test]
fn steps_follow_every_setpoint_without_drift_within_the_step_rate() {
    for name in ["butterfly", "fan"] {
        let sps = setpoints(name);
        let cfg = config(200.0, 100_000.0);
        let start = sps[0].pos_mm;
        let gen = StepGen::new(cfg, PERIOD_NS, start).unwrap();
        let origin = gen.position_steps();
        let mut sink = StepDirSink::new(gen, Recorder::default());
        for sp in &sps {
            sink.put(sp).unwrap();
        }
        let rec = sink.release();
        assert_eq!(rec.after.len(), sps.len());
        let mut total = 0usize;
        for (k, (sp, after)) in sps.iter().zip(&rec.after).enumerate() {
            for axis in 0..AXES {
                let want = (sp.pos_mm[axis] * cfg.steps_per_mm[axis]).round() as i64;
                assert_eq!(origin[axis] + after[axis], want, "{name}: tick {k}, axis {axis}");
            }
        }
        let min_spacing = (1e9 / cfg.max_step_hz).max(f64::from(cfg.step_len_ns + cfg.step_space_ns));
        for (axis, edges) in rec.edges.iter().enumerate() {
            total += edges.len();
            let closest = edges.windows(2).map(|w| w[1] - w[0]).min().unwrap_or(u64::MAX);
            assert!(
                closest as f64 >= min_spacing,
                "{name}: axis {axis}: two steps {closest} ns apart (at least {min_spacing} ns)"
            );
        }
        eprintln!("{name}: {} ticks, {total} steps", sps.len());
        assert!(total > 10_000);
    }
}

#[test]
fn a_step_rate_too_low_for_the_plan_is_refused_and_nothing_moves() {
    let sps = setpoints("butterfly");
    // 8 kHz at 200 steps/mm is 40 mm/s: the Butterfly runs faster
    let cfg = config(200.0, 8_000.0);
    let gen = StepGen::new(cfg, PERIOD_NS, sps[0].pos_mm).unwrap();
    assert_eq!(gen.max_steps_per_period(), 1);
    let mut sink = StepDirSink::new(gen, Recorder::default());
    let mut refused = None;
    for sp in &sps {
        let before = sink.generator().position_steps();
        match sink.put(sp) {
            Ok(()) => {}
            Err(StepSinkError::Steps(e)) => {
                assert_eq!(sink.generator().position_steps(), before);
                refused = Some(e);
                break;
            }
            Err(StepSinkError::Output(e)) => match e {},
        }
    }
    match refused {
        Some(StepError::TooManySteps { steps, max: 1, .. }) => assert!(steps > 1),
        other => panic!("{other:?}"),
    }
}
