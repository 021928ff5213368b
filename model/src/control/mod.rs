//! The 1 kHz link-position controller of the actuator (issue 4): trajectories, a
//! scheduled PID with feed-forward, free-play compensation, a blended torque estimate and
//! live torque/current limits, all in integer fixed point (no floats, no allocation, no
//! panics), bit-identical on the host and on Cortex-M.
//!
//! # Plant (design.md §3), referred to the gearbox output
//!
//! The H-bridge applies V = duty·V_s/1000. The armature current is algebraic (inductance
//! neglected), i = (V − k_e·ω_g)/R, so the motor is a torque source k_t·V/R with a strong
//! viscous damping b_m = k_t·k_e/R (+ gear viscous b_v) ≈ 0.2425 N·m·s/rad: the gear alone
//! has a time constant J_g/b_m = 13 ms. The gear (J_g = 3.2e-3 kg·m²) drives the link
//! (J_l) through the beams (k = 57 … 7167 N·m/rad, dead zone ±φ_b, friction hysteresis).
//! From V to the link angle:
//!
//! θ_l/V = (k_t/R)·k / (s·[J_g·J_l·s³ + b_m·J_l·s² + k·(J_g + J_l)·s + b_m·k])
//!
//! i.e. a rigid body J = J_g + J_l with damping b_m (pole at b_m/J ≈ 58 rad/s) and a
//! lightly damped (ζ ≈ 0.03) coupling mode near √(k(1/J_g + 1/J_l)) (274 rad/s at
//! L = 5 mm, 3070 rad/s at L = 1 mm). The link alone on the spring rings at the
//! anti-resonance ω_a = √(k/J_l) (239 … 2677 rad/s).
//!
//! # Structure (per tick)
//!
//! 1. **Sensors**: the link encoder is unwrapped; the link angle is the centre of the
//!    count, θ_l = (n + ½)·2π/4096. The current is i = (adc − 2048)/1024 A.
//! 2. **Back-EMF observer**: because i is algebraic, the gear velocity at the end of the
//!    last tick is ω_g = (V_applied − R·i)/k_e (resolution 4e-3 rad/s per ADC count), with
//!    no differentiation.
//! 3. **Torque estimate** (coupling torque on the link): current-based
//!    τ_i = k_t·i − J_g·Δω_g/dt − b_v·ω_g; with the gear pot, deflection-based
//!    τ_d = k·dz(θ_g − θ_l, φ_b); blended τ = τ_i + w·(τ_d − τ_i) by inverse variance,
//!    w = σ_i²/(σ_i² + σ_d²), σ_d = k·q_pot/√12 (the pot count q_pot = 0.29° is 0.29 N·m
//!    of torque at L = 5 mm, 36.7 N·m at L = 1 mm), σ_i the configured model uncertainty
//!    of the current-based estimate (default 0.02 N·m). So w = 0.054 at L = 5 mm,
//!    4e-6 at L = 1 mm. Without the pot, τ = τ_i.
//! 4. **Reference** r, ṙ, r̈ from [`trajectory`].
//! 5. **Error** e = r − θ_l, set to 0 while r lies in the measured encoder count (the
//!    measurement cannot tell better): no integration and no proportional action on
//!    quantisation noise, which is what keeps the output steady (no hunting) at rest.
//! 6. **Feed-forward** (rigid inverse model): u_ff = (1000/V_s)·[(k_e + R·b_v/k_t)·ṙ +
//!    (R/k_t)·J·r̈], J = J_g + J_l.
//! 7. **Free-play and compliance compensation**: the coupling needs the deflection
//!    φ_ref = τ_ref/k + φ_b·sat(τ_ref/τ_w) to transmit τ_ref = J_l·r̈ + τ_load, where
//!    τ_load is the load the integrator holds (k_t/R·V_I) and τ_w = 0.1 N·m. The gear,
//!    a back-EMF-damped velocity source, moves by exactly ∫ΔV dt/k_e for extra voltage, so
//!    the compensation adds u_defl = (1000/V_s)·k_e·Δφ_ref/dt: when the needed torque
//!    changes sign the gear is driven across the dead zone 2φ_b (a dead-zone inverse on
//!    the gear side, open loop, no gear-angle measurement needed); at soft settings it
//!    also pre-deflects the spring. (Measured: with a constant load the coupling never
//!    crosses the dead zone; without load, in the 1 Hz sine, the rattle in the free play
//!    dominates the error and this open-loop inverse changes it little.)
//! 8. **PID**: u = u_ff + u_defl + K_p·e + I + K_d·(F(ṙ) − F(ω_g)). The derivative acts on
//!    the *measured* velocity (no derivative kick on steps) of the gear, from the
//!    back-EMF observer: collocated with the motor, so it damps the gear–link mode instead
//!    of destabilising it as the non-collocated link velocity did at L = 3–4 mm (a 67 Hz
//!    limit cycle in the first trials); F is the first-order filter α = dt/(τ_f + dt),
//!    τ_f = 1/(4·ω_c), applied to ṙ too so that its lag is not a tracking error. The
//!    filtered link-encoder velocity is kept as well (ω̂_l, reported for logs).
//!    **Integrator** I (duty ‰, I32F32): outside the reference's count it integrates
//!    K_i·e·dt, only while |e| < max_duty/K_p (integral separation: farther away the P term
//!    saturates anyway and integrating there overshoots); inside the count it integrates
//!    −K_p·(ω_g − ṙ)·dt with a dead band of 1.5 ADC counts of observer resolution — a
//!    virtual spring K_p on the gear that stops the slow creep an imperfect I would
//!    otherwise cause (the motor alone is only a damper at zero speed); at rest ω_g = 0
//!    and the output is constant.
//! 9. **Braking governor** (stationary reference: raw steps, holds): if the gear
//!    approaches the target faster than half the current-limited deceleration can stop it,
//!    ω_g² > 2·a_b·|e|, a_b = ½·k_t·i_lim/J, the output goes to the braking clamp now.
//!    Products only, no square root. It cut the raw-step overshoot with an assisting load
//!    from 11 % to 1 % at L = 4 mm.
//! 10. **Limits**: the duty is clamped to the current window about the back-EMF,
//!     (1000/V_s)·(k_e·ω_g ± R·i_lim), and to ±max_duty. i_lim = min(max current, max
//!     motor torque/k_t, τ_lim/(k_t·a)), τ_lim = margin·τ_cap(L) (default margin 0.85)
//!     and a = max(1, (3J_l − J_g)/(J_g + J_l)) the worst overshoot of the coupling torque
//!     for a step of motor torque on the two-mass system: after a step from τ₀ to τ₁ the
//!     coupling torque peaks at 2·(r·τ₁ + (1 − r)·τ₀) − τ₀ with r = J_l/(J_g + J_l), which
//!     stays within max|τ_m| for r ≤ ½ and within (4r − 1)·max|τ_m| above. The flags say
//!     which clamp is active (torque: the beam-derived current limit binds, or |τ̂| > τ_lim;
//!     current: the motor's; duty: the supply). **Anti-windup**: the integrator stops while
//!     the output is clamped in the direction it would push, and is bounded to ±max_duty.
//!
//! # Gain schedule (computed in [`Schedule::new`], never per tick)
//!
//! The rigid model with the PID and the feed-forward gives the error dynamics
//! J·s³ + (b_m + c·K_d)·s² + c·K_p·s + c·K_i = 0 in volts, c = k_t/R. Placing a triple
//! pole at −ω_c, (s + ω_c)³:
//!
//! * K_p = 3·ω_c²·J/c, K_i = ω_c³·J/c, K_d = max(0, 3·ω_c·J − b_m)/c (V per rad…),
//!   times 1000/V_s for ‰;
//! * ω_c = min(60 rad/s, ω_a/5), ω_a = √(k/J_l): the loop stays well below the coupling
//!   mode (gain margin at soft settings) and, at stiff ones, within what the encoder
//!   resolution (a count is 1.5e-3 rad) and the duty headroom allow. For the paper preset
//!   and J_l = 1e-3 kg·m²: ω_c = 47.9 rad/s at L = 5 mm and 60 rad/s at L ≤ 4 mm
//!   (K_p = 30 250 ‰/rad, K_i = 605 000 ‰/(rad·s), K_d = 342 ‰·s/rad at 60 rad/s).
//!
//! Overrides: a bandwidth, or explicit gains ([`GainOverride`]).
//!
//! # Formats
//!
//! Per-tick signals are Q16 `i32` (I16F16 bits: duty in ‰, angles in rad, velocities in
//! rad/s, accelerations in rad/s², currents in A, torques in N·m; range ±32 768,
//! resolution 1.5e-5), absolute angles and the integrator I32F32 `i64`. Constants are
//! [`Gain`]s (32-bit mantissa + shift). Every operation saturates.
//!
//! # Cost of [`Controller::step`]
//!
//! About 25 Q16 gain multiplies (one `SMULL`, a 64-bit shift and a saturation each, ~10
//! instructions), three 16×64-bit products (observer, pot), a few dozen saturating adds and
//! compares; the minimum-jerk evaluation adds 12 I32F32 products through 64×64→128-bit
//! multiplies during a move (none while holding; two table interpolations and three
//! 32×32 products for a sine). Code size on thumbv7m (release, no LTO): 1 456
//! instructions for `step` and 892 for `Trajectory::advance`, both mostly straight-line
//! saturation branches of which one path runs: an estimated 400–600 instructions per tick
//! while holding and 1 000–1 300 during a move, within the 2 000 budget (not yet measured
//! under QEMU icount).

pub mod config;
pub mod controller;
pub mod gain;
pub mod sine;
pub mod trajectory;

pub use config::{
    encoder_delta, ClutchSetting, Config, ControlError, GainOverride, Limits, MotorParams,
    PidGains, Schedule, SensorCal,
};
pub use controller::{Controller, Flags, Measurements, Output, POT_COUNT_Q32};
pub use gain::Gain;
pub use trajectory::{Command, Reference, Trajectory};
