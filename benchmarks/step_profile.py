"""Where one simulator step goes at the environments' settings: a phase-by-phase table.

    python benchmarks/step_profile.py [--n 300] [--mason 1,0.2] [--warmup-strain 2] [--steps 100]
                                      [--reps 40] [--state-dir /tmp/step_profile_states] [--env-steps 2]

Settings of the environments (``dipenv/envs/field_control.py``): phi = 0.45, solver tolerance 1e-6, Ewald
accuracy 1e-4, ``max_displacement`` 4e-3, exact near field (cut-off 4 a), field along ``y``. For each Mason
number a warmed state is made once and kept in ``--state-dir`` (so that two source trees time the same
configurations): a start state of the N-particle test library when it is in the cache (5 strains of pure
shear at these settings), else a random packing sheared for 5 strains without the field; then
``--warmup-strain`` strains with the field on (the contact network of the field builds up). Each phase is
then re-run ``--reps`` times on the warmed configuration (minimum and median, milliseconds):

* shear term: pair list (``build_pair_list`` at ``2 + lubrication_cutoff``), lubrication scalars and
  blocks, strain forcing and repulsion, elimination order and relabelling, PCG (with its iterations; the
  warm start is the state's extrapolated guess), lubrication stresslets;
* DIP term: Ewald real space, Ewald Fourier space (the two kernels of ``dip_far_field``; their stress
  sums are inside them), near-field blend (its own pair list at ``r_c = 4`` and the near-field stresses
  included) and the pair list alone;
* overlap removal after one explicit step of the measured velocities;
* the whole term functions and ``evaluate``, then ``--steps`` compiled steps (``sim.stepper.advance``),
  and ``Simulation.advance_to`` over 0.25 strain with the compiled time subtracted (Python overhead);
* with ``--env-steps`` > 0: ``dipenv/FieldMagnitude-v0`` (``n_particles=N, target_viscosity=6.1``) from
  test state 0 at a constant Mn, per env step the wall time and the time inside the compiled ``advance``.

One core (``NUMBA_NUM_THREADS=1``); run it alone, the second core busy shifts every number by +-20%.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import statistics
import time
from collections.abc import Callable, Iterator
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import sim  # noqa: E402
from sim import Simulation, SimulationConfig, SimulationState  # noqa: E402

ENV_SETTINGS = {
    "volume_fraction": 0.45,
    "solver_tolerance": 1e-6,
    "ewald_accuracy": 1e-4,
    "max_displacement": 4e-3,
    "time_step": 2e-3,
    "near_field": "exact",
    "near_field_cutoff": 4.0,
}


def config_for(n: int, mason: float, seed: int = 0) -> SimulationConfig:
    """The environments' simulator settings at ``n`` particles and Mason number ``mason``."""
    return SimulationConfig(n_particles=n, mason_number=mason, strain=100.0, seed=seed, **ENV_SETTINGS)


def _library_state(n: int) -> SimulationState | None:
    """Test start state 0 of the cached N-particle library at the environments' settings, if any."""
    root = Path(os.environ.get("DIPENV_CACHE_DIR", Path.home() / ".cache" / "dipenv")) / "states"
    for library in sorted(root.glob("*/library.json")) if root.exists() else []:
        meta = json.loads(library.read_text())
        c = meta.get("config", {})
        if (
            c.get("n_particles") == n
            and c.get("solver_tolerance") == 1e-6
            and c.get("ewald_accuracy") == 1e-4
        ):
            files = sorted(library.parent.glob("test_00000_*.npz"))
            if files:
                with np.load(files[0]) as data:
                    return SimulationState.from_arrays(data)
    return None


def warmed_state(n: int, mason: float, warmup: float, state_dir: Path) -> SimulationState:
    """The configuration the phases are timed on (made once, then read from ``state_dir``)."""
    path = state_dir / f"n{n}_mn{mason:g}_warm{warmup:g}.npz"
    if path.exists():
        return SimulationState.load(path)
    state_dir.mkdir(parents=True, exist_ok=True)
    start = _library_state(n)
    simulation = Simulation(config_for(n, math.inf), state=start, keep_records=False)
    if start is None:
        simulation.advance_to(5.0)
    simulation.set_field(mason, (0.0, 1.0, 0.0))
    simulation.advance_to(simulation.state.time + warmup)
    simulation.state.save(path)
    return simulation.state


def timed(fn: Callable[[], object], reps: int) -> tuple[float, float]:
    """Minimum and median wall time of ``fn()`` over ``reps`` calls after one untimed call (ms)."""
    fn()
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * min(times), 1e3 * statistics.median(times)


def whole_steps(
    n: int, mason: float, state: SimulationState, steps: int, repeats: int = 3
) -> dict[str, float]:
    """``steps`` compiled steps from ``state``, ``repeats`` times from the same state: ms per step (minimum
    and median over the repeats), steps per strain, s per strain (at the minimum), mean PCG iterations."""
    config = config_for(n, mason)
    per_step = []
    for _ in range(repeats):
        simulation = Simulation(config, state=state, keep_records=False)
        t0 = time.perf_counter()
        chunk = simulation.advance(steps)
        per_step.append((time.perf_counter() - t0) / steps)
    mean_dt = float(chunk.time_step.mean())
    return {
        "n": n,
        "mason": mason,
        "ms_step": 1e3 * min(per_step),
        "ms_step_median": 1e3 * statistics.median(per_step),
        "steps_per_strain": 1.0 / mean_dt,
        "seconds_per_strain": min(per_step) / mean_dt,
        "iterations_mean": float(chunk.solver_iterations.mean()),
    }


def profile(
    n: int, mason: float, state: SimulationState, steps: int, reps: int
) -> list[tuple[str, float, float, str]]:
    """Rows ``(phase, min ms, median ms, note)`` for the warmed ``state``."""
    from sim.contacts.repulsion import repulsive_forces
    from sim.dipolophoresis import ewald
    from sim.dipolophoresis.far_field import DEP_T_COEFFICIENT, ICEP_S_COEFFICIENT, ICEP_T_COEFFICIENT
    from sim.dipolophoresis.near_field_blend import add_near_field_corrections
    from sim.geometry.box import lees_edwards_offset, wrap_positions
    from sim.geometry.neighbors import build_pair_list
    from sim.geometry.overlap import remove_overlaps
    from sim.hydrodynamics.elimination_order import elimination_order, relabel_system
    from sim.hydrodynamics.lubrication import (
        assemble_resistance,
        pair_scalars,
        pair_stresslets,
        strain_forcing,
    )
    from sim.hydrodynamics.resistance_solver import solve_resistance_in_order
    from sim.hydrodynamics.stokes_drag import FORCE_DRAG, TORQUE_DRAG
    from sim.observables.stress import N_CONTRIBUTIONS
    from sim.step_parameters import field_parameters
    from sim.stepper import choose_time_step, dipolophoresis_term, evaluate, hydrodynamic_term

    config = config_for(n, mason)
    simulation = Simulation(config, state=state, keep_records=False)
    params = simulation._params
    s = simulation.state
    field = field_parameters(config, s.mason_number, s.field_direction, simulation._plan)
    plan = simulation._plan
    x = s.positions.copy()
    length = params.box_length
    offset = lees_edwards_offset(s.strain, length)
    ratio = s.step_history[0] / s.step_history[1] if s.step_history[1] > 0 else 1.0
    guess = s.warm_start + ratio * (s.warm_start - s.previous_warm_start)
    rows: list[tuple[str, float, float, str]] = []

    def add(name: str, fn: Callable[[], object], note: str = "", r: int = reps) -> None:
        lo, med = timed(fn, r)
        rows.append((name, lo, med, note))

    cut = 2.0 + params.lubrication_cutoff
    pairs, seps = build_pair_list(x, length, offset, cut)
    add("pair list (lubrication)", lambda: build_pair_list(x, length, offset, cut), f"{pairs.shape[0]} pairs")
    sc, units, gaps = pair_scalars(pairs, seps, params.lubrication_cutoff, params.lubrication_regularisation)
    add(
        "lubrication scalars + blocks",
        lambda: assemble_resistance(
            n,
            pairs,
            *pair_scalars(pairs, seps, params.lubrication_cutoff, params.lubrication_regularisation)[1::-1],
            FORCE_DRAG,
            TORQUE_DRAG,
        ),
    )
    diag, off = assemble_resistance(n, pairs, units, sc, FORCE_DRAG, TORQUE_DRAG)
    e_inf = np.zeros((3, 3))
    e_inf[0, 1] = e_inf[1, 0] = 0.5 * params.shear_rate

    def forcing() -> np.ndarray:
        rhs = strain_forcing(n, pairs, units, sc, e_inf)
        forces, _ = repulsive_forces(n, pairs, units, gaps, params.repulsion_scale, params.repulsion_range)
        rhs[:, :3] += forces
        return rhs

    add("strain forcing + repulsion", forcing)
    rhs = forcing()
    add(
        "elimination order + relabel",
        lambda: relabel_system(diag, off, pairs, elimination_order(off, pairs, n)),
    )
    order = elimination_order(off, pairs, n)
    od, oo, op = relabel_system(diag, off, pairs, order)
    orhs = rhs[order]
    oguess = guess[order]
    sol, iterations, _ = solve_resistance_in_order(
        od, oo, op, orhs, oguess, params.solver_tolerance, params.solver_max_iterations
    )
    add(
        "PCG (DILU, Eisenstat)",
        lambda: solve_resistance_in_order(
            od, oo, op, orhs, oguess, params.solver_tolerance, params.solver_max_iterations
        ),
        f"{iterations} iterations",
    )
    disturbance = np.empty_like(sol)
    disturbance[order] = sol
    from sim.hydrodynamics import lubrication

    if hasattr(lubrication, "pair_stresslet_sum"):  # what the step uses (issue 22), else the older path
        add(
            "lubrication stress (sum)",
            lambda: lubrication.pair_stresslet_sum(pairs, units, sc, disturbance, e_inf),
        )
    else:
        add("lubrication stresslets", lambda: pair_stresslets(n, pairs, units, sc, disturbance, e_inf))

    q = np.outer(field.direction, field.direction) - np.eye(3) / 3.0
    a_s = ICEP_S_COEFFICIENT * field.icep_weight
    a_t = ICEP_T_COEFFICIENT * field.icep_weight + DEP_T_COEFFICIENT * field.dep_weight

    def real() -> None:
        ewald._real_space_sums(
            x,
            length,
            offset,
            plan.splitting,
            plan.real_cutoff,
            q,
            a_s,
            a_t,
            np.zeros((n, 3)),
            np.zeros((2, 6)),
        )

    def fourier() -> None:
        ewald._ewald_fourier_sums(
            x,
            length,
            offset,
            plan.splitting,
            plan.k_cutoff,
            q,
            a_s,
            a_t,
            np.zeros((n, 3)),
            np.zeros((3, 3)),
            np.zeros((3, 3)),
        )

    waves = ewald._half_space_waves(plan.k_cutoff, length)
    add("Ewald real space", real, f"xi {plan.splitting:.3f}, r_c {plan.real_cutoff:.2f}")
    add("Ewald Fourier space", fourier, f"k_c {plan.k_cutoff:.2f}, ~{waves:.0f} waves")
    near_pairs = build_pair_list(x, length, offset, field.near_field_cutoff)[0].shape[0]
    add(
        "near-field pair list (r_c = 4)",
        lambda: build_pair_list(x, length, offset, field.near_field_cutoff),
        f"{near_pairs} pairs",
    )

    def blend() -> None:
        add_near_field_corrections(
            x,
            length,
            offset,
            field.direction,
            field.icep_weight,
            field.dep_weight,
            field.near_field_cutoff,
            field.near_field_taper,
            field.near_field_tables,
            np.zeros((n, 3)),
            np.zeros((3, 3)),
            np.zeros((3, 3)),
            np.zeros((3, 3)),
        )

    add("near-field blend + DIP pair stresses", blend, "own pair list included")
    if hasattr(ewald, "dip_far_field_with_pairs"):  # the step's path since issue 22: shared enumeration
        from sim.dipolophoresis.near_field_blend import add_pair_corrections

        def real_with_pairs() -> tuple:
            return ewald._real_space_sums(
                x,
                length,
                offset,
                plan.splitting,
                plan.real_cutoff,
                q,
                a_s,
                a_t,
                np.zeros((n, 3)),
                np.zeros((2, 6)),
                field.near_field_cutoff,
            )

        shared_pairs, shared_separations = real_with_pairs()
        add("Ewald real space + near pairs", real_with_pairs, f"{shared_pairs.shape[0]} near pairs")

        def blend_given() -> None:
            add_pair_corrections(
                shared_pairs,
                shared_separations,
                length,
                field.direction,
                field.icep_weight,
                field.dep_weight,
                field.near_field_cutoff,
                field.near_field_taper,
                field.near_field_tables,
                np.zeros((n, 3)),
                np.zeros((3, 3)),
                np.zeros((3, 3)),
                np.zeros((3, 3)),
            )

        add("near-field blend, given pairs", blend_given)
    stress = np.zeros((N_CONTRIBUTIONS, 3, 3))
    add("shear term (whole)", lambda: hydrodynamic_term(x, s.strain, guess, params, stress))
    add("DIP term (whole)", lambda: dipolophoresis_term(x, s.strain, params, field, stress))
    add("evaluate (both terms)", lambda: evaluate(x, s.strain, guess, params, field))

    velocity, dist, dip_velocity, _, _, _ = evaluate(x, s.strain, guess, params, field)
    non_affine = float(np.sqrt(((dist[:, :3] + dip_velocity) ** 2).sum(axis=1).max()))
    dt = choose_time_step(non_affine, s.step_history[0], True, params)
    moved = x + dt * velocity
    strain1 = s.strain + params.shear_rate * dt
    offset1 = lees_edwards_offset(strain1, length)
    wrap_positions(moved, length, offset1)
    sweeps, _ = remove_overlaps(
        moved.copy(), length, offset1, params.overlap_min_gap, params.overlap_max_sweeps
    )
    add(
        "overlap removal",
        lambda: remove_overlaps(
            moved.copy(), length, offset1, params.overlap_min_gap, params.overlap_max_sweeps
        ),
        f"{sweeps} sweeps",
    )

    whole = whole_steps(n, mason, state, steps)
    rows.append(
        (
            "whole step (advance)",
            whole["ms_step"],
            whole["ms_step_median"],
            f"{whole['iterations_mean']:.1f} iterations, {whole['steps_per_strain']:.0f} steps/strain, "
            f"{whole['seconds_per_strain']:.2f} s/strain",
        )
    )

    # Python overhead of advance_to: the wall time less the time inside the compiled advance
    with timed_advance() as compiled:
        sim3 = Simulation(config, state=state)
        t0 = time.perf_counter()
        records = sim3.advance_to(sim3.state.time + 0.25)
        wall = time.perf_counter() - t0
    rows.append(
        (
            "advance_to(0.25 strain): Python",
            1e3 * (wall - compiled[0]),
            1e3 * (wall - compiled[0]),
            f"of {1e3 * wall:.0f} ms, {records.strain.size} steps",
        )
    )
    return rows


@contextlib.contextmanager
def timed_advance() -> Iterator[list[float]]:
    """Within the block, ``sim.simulation`` calls a wrapper of the compiled ``advance`` that adds the
    seconds spent inside it to the yielded ``[seconds]`` (so the caller's wall time less it is Python)."""
    import sim.simulation as simulation_module
    from sim.stepper import advance

    compiled = [0.0]

    def timed(*args: object) -> tuple:
        t0 = time.perf_counter()
        out = advance(*args)
        compiled[0] += time.perf_counter() - t0
        return out

    simulation_module.advance = timed  # type: ignore[assignment]
    try:
        yield compiled
    finally:
        simulation_module.advance = advance  # type: ignore[assignment]


def env_profile(n: int, mason: float, env_steps: int) -> tuple[float, float, int]:
    """Seconds per env step, seconds inside the compiled ``advance`` per env step, simulator steps."""
    import gymnasium as gym

    import dipenv  # noqa: F401
    from agents.open_loop import constant_action

    env = gym.make("dipenv/FieldMagnitude-v0", n_particles=n, target_viscosity=6.1, progress=False)
    with timed_advance() as compiled:
        env.reset(seed=0, options={"split": "test", "index": 0})
        action = np.array(constant_action(env.unwrapped, mason, None), dtype=np.float32)
        env.step(action)  # untimed: the structure adapts to the field
        compiled[0] = 0.0
        wall = 0.0
        sim_steps = 0
        for _ in range(env_steps):
            t0 = time.perf_counter()
            _, _, _, _, info = env.step(action)
            wall += time.perf_counter() - t0
            sim_steps += info["sim_steps"]
    return wall / env_steps, compiled[0] / env_steps, sim_steps // env_steps


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--n", type=int, default=300)
    parser.add_argument("--mason", default="1,0.2")
    parser.add_argument("--warmup-strain", type=float, default=2.0)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--reps", type=int, default=40)
    parser.add_argument("--state-dir", type=Path, default=Path("/tmp/step_profile_states"))
    parser.add_argument("--env-steps", type=int, default=0)
    parser.add_argument(
        "--whole-only",
        action="store_true",
        help="only the whole compiled steps, one JSON line per Mason number (benchmarks/compare_trees.py)",
    )
    args = parser.parse_args()
    Simulation(SimulationConfig(n_particles=64, volume_fraction=0.3, strain=0.01, mason_number=1.0)).advance(
        3
    )
    if args.whole_only:
        for mason in [float(m) for m in args.mason.split(",")]:
            state = warmed_state(args.n, mason, args.warmup_strain, args.state_dir)
            print(json.dumps(whole_steps(args.n, mason, state, args.steps)), flush=True)
        return
    print(f"sim from {Path(sim.__file__).parent}; load {os.getloadavg()[0]:.2f}")
    for mason in [float(m) for m in args.mason.split(",")]:
        state = warmed_state(args.n, mason, args.warmup_strain, args.state_dir)
        rows = profile(args.n, mason, state, args.steps, args.reps)
        print(f"\nN = {args.n}, Mn = {mason:g} (strain {state.strain:.2f})\n")
        print("| phase | min ms | median ms | note |")
        print("|---|---|---|---|")
        for name, lo, med, note in rows:
            print(f"| {name} | {lo:.3f} | {med:.3f} | {note} |")
        if args.env_steps > 0:
            wall, compiled, steps = env_profile(args.n, mason, args.env_steps)
            print(
                f"\nenv step at Mn {mason:g}: {wall:.2f} s, of which compiled advance {compiled:.2f} s "
                f"({100 * (wall - compiled) / wall:.1f}% outside), {steps} simulator steps"
            )


if __name__ == "__main__":
    main()
