//! Every scenario on the host: the step sweep meets the closed-loop targets with no fault,
//! each fault scenario raises its fault within 2 ticks of the condition and keeps the
//! motor off, and a second run gives the same hash.

use plant::scenario::{run_on_host, ScenarioEvent, ScenarioId};

#[test]
fn every_scenario_passes_on_the_host_and_repeats_bit_for_bit() {
    for id in ScenarioId::ALL {
        let mut metrics = Vec::new();
        let mut log = Vec::new();
        let s = run_on_host(id, |ev| {
            if let ScenarioEvent::SegmentDone {
                clutch_mm,
                metrics: m,
                ..
            } = ev
            {
                metrics.push((*clutch_mm, *m));
            }
            log.push(format!("{ev:?}"));
        })
        .unwrap();
        println!(
            "{:24} hash {:#018x} fault {:?} inject {:?} condition {:?} driven-after {} lines-after {}",
            id.name(),
            s.hash,
            s.first_fault,
            s.inject_tick,
            s.condition_tick,
            s.driven_after_fault,
            s.lines_driving_after_fault
        );
        assert!(s.passed(), "{}: {s:?}\n{}", id.name(), log.join("\n"));
        if id == ScenarioId::StepSweep {
            assert_eq!(metrics.len(), 5);
            for (mm, m) in &metrics {
                println!(
                    "  L = {mm} mm: overshoot {:.2} %, settling {:?} s, ss error {:.2} counts, peak stress {:.3} σ_allow, rms {:.3e} rad, torque-limited {}",
                    m.overshoot_pct, m.settling_time_s, m.steady_state_error_counts, m.peak_stress_ratio, m.rms_error_rad, m.torque_limited
                );
                assert!(m.overshoot_pct <= 5.0, "{mm} mm: {m:?}");
                assert!(
                    m.settling_time_s.is_some_and(|t| t <= 0.4),
                    "{mm} mm: {m:?}"
                );
                assert!(m.peak_stress_ratio < 1.0, "{mm} mm: {m:?}");
                assert!(m.steady_state_error_counts <= 1.0, "{mm} mm: {m:?}");
            }
        }
        let again = run_on_host(id, |_| {}).unwrap();
        assert_eq!(again, s, "{}", id.name());
    }
}
