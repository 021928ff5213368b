"""The shortest raw step the elastic actuator's linear part allows (docs/design.md §10,
"The elastic actuator's bound").

The acceptance bound for raw steps is 1.5 times the time-optimal move of the *rigid*
actuator (§10). This asks what the elastic one could do with perfect knowledge: the least
time T after which some open-loop voltage sequence, held for a tick at a time, brings the
link within one encoder count of the target and keeps it there, under the supply, current
and beam-torque limits of that bound. The gear and the link are two masses on the beams'
stiffness k(L) (§2), the motor as in §3 (R, k_t, k_e, J_g, b_v), the link's bearing
viscous; the free play and the dry friction are left out (they are not linear). For each
T the question is a linear program (feasibility; HiGHS through scipy), and T is found by
bisection.

Input: the grid's dump files (`VSA_GRID_DUMP=PREFIX cargo test --release -p host-tests
--test grid` writes PREFIX.SEED.tsv for each grid it runs); their loaded raw steps are
read from the `vsa simulate` column, each on the actuator its `--plant` overrides make (an
off-nominal grid's), known exactly; T_opt is that actuator's rigid bound, as in the grid. Output: one line per step and a summary.
`--links 0.5,1,2,3` asks for one sequence that serves links of those multiples of the
configured inertia at once (an open-loop plan for a link known within that range). Run it
with `cargo xtask flex-bound FILE...` (which installs numpy and scipy into target/venv);
`--check` checks the program against the rigid bound.
"""

import argparse
import collections
import math
import multiprocessing
import re
import sys

import numpy as np
import scipy.linalg
import scipy.sparse
from scipy.optimize import linprog

# The motor of docs/design.md §3 (supply V, resistance Ω, k_t N·m/A, k_e V·s/rad, J_g kg·m²)
# and the limits of the rigid bound (§10).
Motor = collections.namedtuple("Motor", "supply resistance kt ke jg")
NOMINAL = Motor(supply=12.0, resistance=8.0, kt=1.0, ke=1.94, jg=3.2e-3)
# The grid's `--plant` overrides that enter the linear model: name → Motor field, or "link".
OVERRIDES = {"supply": "supply", "resistance": "resistance", "torque-constant": "kt",
             "back-emf": "ke", "gear-inertia": "jg", "link-inertia": "link"}
GEAR_VISCOUS = 1e-3
LINK_VISCOUS = 2e-4
CURRENT_LIMIT_A = 1.5
TORQUE_MARGIN = 0.85
# The paper preset's beams (§2.2).
YOUNG = 200e9
BEAM_RADIUS = 0.5e-3
PITCH_RADIUS = 7.8e-3
BEAMS = 4
SIGMA_ALLOW = 1.5e9
COUNT_RAD = 2 * math.pi / 4096
DT = 1e-3
# The acceptance bound on a raw step's settling, times T_opt (the grid's
# `RAW_STEP_BOUND_FACTOR`, host-tests/src/grid.rs).
BOUND_FACTOR = 1.5
# Ticks the link must stay within a count after T before it is at rest.
HOLD_TICKS = 150
# HiGHS' interior-point method, then its dual simplex: near the least time either stalls
# or gives up on some programs; a time neither decides counts as not reached.
METHODS = ("highs-ipm", "highs-ds")
TIME_LIMIT_S = 10.0
# The longest step looked for, ticks.
MAX_TICKS = 2000


def stiffness(l_m):
    """k = 12·E·I·R²/L³ (§2: four cantilevers, 3·E·I/L³ each, at the pitch radius R)."""
    return 12 * YOUNG * (math.pi * BEAM_RADIUS**4 / 4) * PITCH_RADIUS**2 / l_m**3


def torque_capacity(l_m):
    """τ_cap = n·R·σ_allow·π·r³/(4·L) (§10)."""
    return BEAMS * PITCH_RADIUS * SIGMA_ALLOW * math.pi * BEAM_RADIUS**3 / (4 * l_m)


def rigid_time_optimal(h, j_l, l_m, motor=NOMINAL):
    """The rigid bound of §10: full voltage within the current limit, then braking at the
    current limit, the link's acceleration within the beams' torque limit."""
    j = motor.jg + j_l
    a_link = TORQUE_MARGIN * torque_capacity(l_m) / j_l
    a_brake = min(motor.kt * CURRENT_LIMIT_A / j, a_link)
    theta = w = t = 0.0
    dt = 1e-6
    while h - theta > w * w / (2 * a_brake):
        i = min((motor.supply - motor.ke * w) / motor.resistance, CURRENT_LIMIT_A)
        w += min(motor.kt * i / j, a_link) * dt
        theta += w * dt
        t += dt
    return t + w / a_brake


def discrete(k, j_l, motor):
    """x = (θ_g, ω_g, θ_l, ω_l), inputs (V, τ_load): the zero-order-hold model over one tick."""
    damping = motor.kt * motor.ke / motor.resistance + GEAR_VISCOUS
    a = np.array([
        [0, 1, 0, 0],
        [-k / motor.jg, -damping / motor.jg, k / motor.jg, 0],
        [0, 0, 0, 1],
        [k / j_l, 0, -k / j_l, -LINK_VISCOUS / j_l],
    ])
    b = np.array([[0, 0], [motor.kt / (motor.resistance * motor.jg), 0], [0, 0], [0, 1 / j_l]])
    m = np.zeros((6, 6))
    m[:4, :4] = a * DT
    m[:4, 4:] = b * DT
    e = scipy.linalg.expm(m)
    return e[:4, :4], e[:4, 4:]


class Rows:
    """Linear constraints built row by row: Σ val·x[col] (= or ≤) rhs."""

    def __init__(self):
        self.rows, self.cols, self.vals, self.rhs = [], [], [], []

    def add(self, terms, value):
        for col, val in terms:
            self.rows.append(len(self.rhs))
            self.cols.append(col)
            self.vals.append(val)
        self.rhs.append(value)

    def matrix(self, width):
        return scipy.sparse.csr_matrix((self.vals, (self.rows, self.cols)),
                                       shape=(len(self.rhs), width))


def reachable(ticks, h, l_m, links, load, motor=NOMINAL, stiffer=1.0):
    """Whether one voltage sequence puts the link within a count of h from `ticks` on, at
    rest `HOLD_TICKS` later, from rest under `load` at 0, for each link inertia of `links`
    at once (beams `stiffer` times k(L)); None if the solver decides neither way."""
    k = stiffer * stiffness(l_m)
    n = ticks + HOLD_TICKS
    u = lambda t: t  # noqa: E731  (the voltages, shared)
    nx = 4 * (n + 1)
    width = n + nx * len(links)
    equation, inequality = Rows(), Rows()
    bounds = [(-motor.supply, motor.supply)] * n + [(None, None)] * (nx * len(links))

    torque_limit = TORQUE_MARGIN * torque_capacity(l_m)
    for p, j_l in enumerate(links):
        a, b = discrete(k, j_l, motor)
        x = lambda t, j: n + p * nx + 4 * t + j  # noqa: E731
        start = (-load / k, 0.0, 0.0, 0.0)  # the beams hold the load
        for j in range(4):
            equation.add([(x(0, j), 1.0)], start[j])
        for t in range(n):
            for j in range(4):
                terms = [(x(t + 1, j), 1.0), (u(t), -b[j, 0])]
                terms += [(x(t, m), -a[j, m]) for m in range(4) if a[j, m] != 0]
                equation.add(terms, b[j, 1] * load)
            # |i| ≤ i_max with i = (V − k_e·ω_g)/R, |k·(θ_g − θ_l)| ≤ 0.85·τ_cap.
            for s in (1.0, -1.0):
                inequality.add([(u(t), s / motor.resistance),
                                (x(t, 1), -s * motor.ke / motor.resistance)], CURRENT_LIMIT_A)
                inequality.add([(x(t + 1, 0), s * k), (x(t + 1, 2), -s * k)], torque_limit)
        equation.add([(x(n, 1), 1.0)], 0.0)
        equation.add([(x(n, 3), 1.0)], 0.0)
        for t in range(ticks, n + 1):
            bounds[x(t, 2)] = (h - COUNT_RAD, h + COUNT_RAD)
    for method in METHODS:
        res = linprog(np.zeros(width), A_ub=inequality.matrix(width), b_ub=inequality.rhs,
                      A_eq=equation.matrix(width), b_eq=equation.rhs, bounds=bounds,
                      method=method, options={"time_limit": TIME_LIMIT_S})
        if res.status in (0, 2):  # 0: a sequence exists, 2: none does
            return res.status == 0
    return None


def shortest_ticks(h, l_m, links, load, upper, motor=NOMINAL, stiffer=1.0):
    """The least T in ticks that a solved program reaches (bisection below `upper`, or
    below the first of 2·upper, 4·upper, … up to 2 000 ticks reached); None if none is."""
    lo, hi = 2, upper
    while not reachable(hi, h, l_m, links, load, motor, stiffer):
        if hi >= MAX_TICKS:
            return None
        lo, hi = hi, min(2 * hi, MAX_TICKS)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if reachable(mid, h, l_m, links, load, motor, stiffer):
            hi = mid
        else:
            lo = mid
    return hi


Step = collections.namedtuple("Step", "l_m j_l load h motor controller")


def actuator(args):
    """The motor and the link inertia of a `vsa simulate` line, its `--plant` overrides
    applied (a factor `xF` of the nominal value or an absolute value with its unit)."""
    j_l = float(re.search(r"--inertia (\S+)", args)[1])
    fields = NOMINAL._asdict()
    for name, value in re.findall(r"--plant ([a-z-]+)=(\S+)", args):
        field = OVERRIDES.get(name)
        if field is None:
            continue  # sensor and friction overrides: not in the linear model
        nominal = j_l if field == "link" else fields[field]
        number = float(value[1:]) * nominal if value.startswith("x") else \
            float(re.match(r"[-+0-9.eE]+", value)[0])
        if field == "link":
            j_l = number
        else:
            fields[field] = number
    return Motor(**fields), j_l


def raw_steps(paths, every):
    """The loaded raw steps in the dumps, every `every`-th, with the actuator each ran on
    and the controller's settling / T_opt."""
    steps = []
    for path in paths:
        with open(path, encoding="utf-8") as f:
            header = f.readline().rstrip("\n").split("\t")
            ratio_col = header.index("raw-step settling / T_opt")
            args_col = header.index("vsa simulate")
            for line in f:
                cols = line.rstrip("\n").split("\t")
                args = cols[args_col]
                step = re.search(r"--step=(\S+)rad", args)
                load = float(re.search(r"--load=(\S+)Nm", args)[1])
                if step is None or load == 0.0:
                    continue
                l_m = float(re.search(r"--clutch-length (\S+)mm", args)[1]) * 1e-3
                motor, j_l = actuator(args)
                steps.append(Step(l_m, j_l, load, float(step[1]), motor,
                                  float(cols[ratio_col])))
    return steps[::every]


def bound_of(job):
    """(the step, its rigid bound T_opt, the least ticks of one sequence for the links
    `factors` times the step's own)."""
    step, factors = job
    sign = 1.0 if step.h > 0 else -1.0  # a positive step, the load mirrored with it
    t_opt = rigid_time_optimal(abs(step.h), step.j_l, step.l_m, step.motor)
    links = tuple(f * step.j_l for f in factors)
    ticks = shortest_ticks(abs(step.h), step.l_m, links, sign * step.load,
                           math.floor(BOUND_FACTOR * t_opt / DT), step.motor)
    return step, t_opt, ticks


def check():
    """The program against the rigid bound of §10, computed independently above: with beams
    100 times as stiff the actuator is rigid, and the least time is the rigid one less the
    few ms that landing within a count saves (a shorter time is refused)."""
    rigid_ms = rigid_time_optimal(0.5, 1e-3, 3e-3) * 1e3
    stiff = shortest_ticks(0.5, 3e-3, (1e-3,), 0.0, 200, stiffer=100.0)
    print(f"0.5 rad, J_l 1e-3 kg·m², L = 3 mm: rigid bound {rigid_ms:.1f} ms"
          f" (docs/design.md §10: 107 ms), the program with beams 100 times as stiff"
          f" {stiff} ms")
    if not (abs(rigid_ms - 107.0) < 1.0 and rigid_ms - 6 <= stiff <= rigid_ms + 1):
        sys.exit("flex_bound: the program does not meet the rigid bound")


def factors_arg(text):
    """`--links`: positive factors, comma-separated, as a tuple."""
    try:
        factors = [float(f) for f in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of numbers: {text!r}") from None
    if not all(0 < f < 100 for f in factors):
        raise argparse.ArgumentTypeError(f"factors must be in (0, 100): {text!r}")
    return tuple(factors)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dumps", nargs="*", help="the grid's dump files (TSV)")
    parser.add_argument("--check", action="store_true",
                        help="only check the program against the rigid bound")
    parser.add_argument("--every", type=int, default=1, help="take every N-th loaded raw step")
    parser.add_argument("--jobs", type=int, default=multiprocessing.cpu_count())
    parser.add_argument("--links", default=(1.0,), type=factors_arg,
                        help="factors of the configured link inertia one voltage sequence must"
                        " serve at once, e.g. 0.5,1,2,3 (default 1: the configured link)")
    args = parser.parse_args()
    if args.check:
        check()
        return
    if not args.dumps:
        parser.error("the grid's dump files are needed (or --check)")
    steps = raw_steps(args.dumps, args.every)
    if not steps:
        sys.exit("flex_bound: no loaded raw step in the dumps")
    print("L mm\tJ_l kg·m²\tload N·m\tstep rad\tT_opt ms\telastic bound ms\tbound / T_opt"
          "\tcontroller / T_opt")
    ratios, within, controller_within = [], 0, 0
    with multiprocessing.Pool(args.jobs) as pool:
        jobs = [(step, args.links) for step in steps]
        for step, t_opt, ticks in pool.imap(bound_of, jobs):
            ratio = float("inf") if ticks is None else ticks * DT / t_opt
            ratios.append(ratio)
            within += ratio <= BOUND_FACTOR
            controller_within += step.controller <= BOUND_FACTOR
            print(f"{step.l_m * 1e3:.3f}\t{step.j_l:.3e}\t{step.load:+.3f}\t{step.h:+.3f}"
                  f"\t{t_opt * 1e3:.1f}\t{ticks}\t{ratio:.2f}\t{step.controller:.2f}",
                  flush=True)
    ratios.sort()
    links = ",".join(f"{f:g}" for f in args.links)
    print(f"{len(ratios)} loaded raw steps, links ×{links}: the elastic bound within"
          f" {BOUND_FACTOR:g}·T_opt in {within} (bound / T_opt min {ratios[0]:.2f}, median {ratios[len(ratios) // 2]:.2f},"
          f" max {ratios[-1]:.2f}); the controller within {BOUND_FACTOR:g}·T_opt in"
          f" {controller_within}")


if __name__ == "__main__":
    main()
