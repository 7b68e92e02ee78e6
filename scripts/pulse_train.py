"""Does a pulsed field beat a steady one of the same mean energy? Field protocols at a held shear rate.

    python scripts/pulse_train.py --out DIR [--env dipenv/ThickeningControl-v2] [--rate 4] [--states 4]
        [--intervals 16] [--skip 4] [--protocols steady:0.2,pulse:0.1:off,steady:0.1] [--resume | --overwrite]

The trained PPO policies of the thickening-control study alternate the strongest field with a weak one
or none from one interval to the next at high shear rates (``scripts/field_pulsing.py``). This plays
field protocols in the environment (its physics, start states and reward terms) with the shear rate held
at ``--rate`` (a one-hold ``reset(options={"schedule": ...})``), from the first ``--states`` test start
states, for ``--intervals`` intervals (a truncated episode), and averages each interval's time-averaged
``eta_r``, its excess over the env's cap and the field energy ``<1/Mn_ref>`` over the intervals after the
first ``--skip``. Protocols: ``steady:MN`` (``Mn_ref = MN`` or ``off``) and ``pulse:MN1:MN2[:MN3...]`` (the
fields in turn, one per interval, repeated: ``pulse:0.1:off`` alternates, ``pulse:0.1:0.1:off:off`` has
twice the period, ``pulse:0.1:off:off`` a third of the time on). The time average covers every
instant, so a pulse that lowers it at equal mean energy does so through the suspension's response (the
structure outliving the field), not by how it is sampled.

Writes ``DIR/episodes.json`` (per protocol and state: per-interval eta_r, energy, Mn_ref, eta_r split by
stress contribution, and the microstructure of the observation at each interval's end), reused on rerun
(resumable, keyed by protocol and state), ``DIR/command.txt``, and Markdown tables on stdout: per
protocol the means over states and, for each protocol after the first, the paired difference to the first
(mean ± standard error over states); then, per protocol and phase (a pulse's two fields apart), eta_r by
contribution (hydrodynamic: solvent, Stokes drag and lubrication; repulsion; field: ICEP and DEP) and the
end-of-interval contact number and fabric ``A_yy - 1/3`` (alignment along the field, ``y``). Episodes
stored before the contributions were recorded lack them and are played again.

``DIR`` follows the run-folder protocol (:mod:`agents.folders`): ``manifest.json`` is written first, with the
identity ``--env``, ``--rate`` and ``--intervals`` (what an episode is; ``--states`` and ``--protocols`` add
episodes, ``--skip`` only changes the tables). A rerun of the same identity continues; another rate, say,
is refused (exit 2; it used to replace the stored episodes) unless ``--overwrite`` deletes the whole
previous run. A folder made before manifests (``episodes.json``) is adopted when its episodes were played
with the same identity.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import dipenv  # noqa: F401  (registers the ids)
import sim
from agents.folders import (
    add_folder_options,
    check_parent,
    claim_for_script,
    legacy_markers,
    write_text_atomic,
)


def parse_protocol(text: str) -> list[float]:
    """``steady:MN`` -> [MN]; ``pulse:A:B[:C...]`` -> [A, B, ...] (``off`` -> inf), one field per interval."""
    kind, *values = text.split(":")
    try:
        masons = [math.inf if v == "off" else float(v) for v in values]
    except ValueError:
        masons = []
    if kind == "steady" and len(masons) == 1 or kind == "pulse" and len(masons) >= 2:
        if all(m > 0 for m in masons):
            return masons
    raise ValueError(
        f"a protocol is steady:MN or pulse:MN1:MN2[:MN3...] with Mn_ref > 0 or 'off', got {text!r}"
    )


MICROSTRUCTURE = ("contact_number", "fabric_yy", "fabric_xy", "g_pole", "g_equator")
"""Observation features recorded per interval (the configuration at the interval's end)."""

GROUPS = {
    "hydrodynamic": ("solvent", "stokes_drag", "lubrication"),
    "repulsion": ("repulsion",),
    "field": ("icep_isolated", "icep_pair", "dep_virial", "dep_stresslet"),
}
"""Stress contributions (``sim.STRESS_CONTRIBUTIONS``) summed for the phase table."""


def play(env: gym.Env, masons: list[float], index: int, rate: float, intervals: int) -> dict[str, list]:
    unwrapped: Any = env.unwrapped  # a ThickeningControlEnv
    mapping = unwrapped.mapping
    names = [f.name for f in unwrapped.frame_features()]
    duration = unwrapped.episode_duration + 1.0
    hold = {"times": [0.0, duration], "rates": [rate, rate]}
    env.reset(seed=0, options={"split": "test", "index": index, "schedule": hold})
    out: dict[str, list] = {"eta_r": [], "excess": [], "energy": [], "mason_number": [], "contributions": []}
    out.update({name: [] for name in MICROSTRUCTURE})
    for k in range(intervals):
        action = np.array([mapping.action_for(masons[k % len(masons)])], dtype=np.float32)
        observation, _, terminated, truncated, info = env.step(action)
        if info.get("simulation_failed"):
            raise RuntimeError(f"simulation failed on state {index}, interval {k}")
        out["eta_r"].append(float(info["eta_r"]))
        out["excess"].append(max(0.0, float(info["eta_r"]) - float(info["eta_cap"])))
        out["energy"].append(float(info["field_energy"]))
        m = float(info["mason_number"])
        out["mason_number"].append(m if math.isfinite(m) else "inf")
        out["contributions"].append(info["eta_r_contributions"])
        for name in MICROSTRUCTURE:
            out[name].append(float(observation[names.index(name)]))
        if terminated or truncated:
            break
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], allow_abbrev=False)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--env", default="dipenv/ThickeningControl-v2")
    parser.add_argument(
        "--rate", type=float, default=4.0, help="held shear rate (gammadot_ref), in [1e-3, 1e3]"
    )
    parser.add_argument("--states", type=int, default=4, help="first test start states, >= 2")
    parser.add_argument("--intervals", type=int, default=16, help="intervals per episode, > --skip")
    parser.add_argument("--skip", type=int, default=4, help="leading intervals left out of the means, >= 0")
    parser.add_argument("--protocols", default="steady:0.2,pulse:0.1:off,steady:0.1")
    add_folder_options(parser, "--out")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.rate) and sim.MIN_SHEAR_RATE <= args.rate <= sim.MAX_SHEAR_RATE):
        parser.error(
            f"--rate must be in [{sim.MIN_SHEAR_RATE:g}, {sim.MAX_SHEAR_RATE:g}] (the simulator's shear "
            f"rates), got {args.rate}"
        )
    if args.states < 2:
        parser.error(f"--states must be >= 2 (paired standard errors), got {args.states}")
    if not 0 <= args.skip < args.intervals:
        parser.error(f"--skip must be in [0, --intervals), got {args.skip} with --intervals {args.intervals}")
    try:
        protocols = {name: parse_protocol(name) for name in args.protocols.split(",")}
    except ValueError as error:
        parser.error(f"--protocols: {error}")
    check_parent(parser, args.out)
    if args.env not in dipenv.ENV_IDS or not args.env.startswith("dipenv/ThickeningControl"):
        parser.error(f"--env must be a thickening-control environment of dipenv, got {args.env!r}")
    store = args.out / "episodes.json"
    setup = {"env": args.env, "rate": args.rate, "intervals": args.intervals}
    episodes: dict[str, dict] = {}
    if store.exists() and not args.overwrite:
        try:
            episodes = json.loads(store.read_text())
            setups = [episode["setup"] for episode in episodes.values()]
        except (OSError, ValueError, TypeError, KeyError, AttributeError) as error:
            parser.error(f"--out {args.out}: {store} cannot be read ({type(error).__name__}: {error})")
        other = next((s for s in setups if s != setup), None)
        if other is not None:
            parser.error(
                f"--out {args.out} holds episodes of another setup ({store.name}: {other}; requested "
                f"{setup}); choose another --out, or give --overwrite to delete that run"
            )
    claim_for_script(
        parser,
        args.out,
        "pulse_train.py",
        setup,
        argv=argv,
        resume=args.resume,
        overwrite=args.overwrite,
        legacy=legacy_markers(args.out, ("episodes.json",), script="pulse_train.py"),
    )
    if args.overwrite:
        episodes = {}
    env = gym.make(args.env)
    for name, masons in protocols.items():
        for index in range(args.states):
            key = f"{name}/{index}"
            if key in episodes and episodes[key]["setup"] == setup and "contributions" in episodes[key]:
                continue
            episodes[key] = {"setup": setup, **play(env, masons, index, args.rate, args.intervals)}
            write_text_atomic(store, json.dumps(episodes))
            print(f"{key}: done", file=sys.stderr, flush=True)
    env.close()

    def means(name: str, quantity: str) -> np.ndarray:
        return np.array([np.mean(episodes[f"{name}/{i}"][quantity][args.skip :]) for i in range(args.states)])

    first = next(iter(protocols))
    print(
        f"{args.env}, shear rate held at {args.rate:g}, test states 0-{args.states - 1}, intervals "
        f"{args.skip + 1}-{args.intervals} averaged; differences paired per state against {first}\n"
    )
    print("| protocol | eta_r | excess over the cap | field energy | d eta_r ± se | d excess ± se |")
    print("|---|---|---|---|---|---|")
    for name in protocols:
        eta, excess, energy = (means(name, q) for q in ("eta_r", "excess", "energy"))
        row = f"| {name} | {eta.mean():.3f} | {excess.mean():.3f} | {energy.mean():.3f} |"
        if name == first:
            print(row + " | |")
            continue
        d_eta, d_excess = eta - means(first, "eta_r"), excess - means(first, "excess")
        se = math.sqrt(args.states)
        print(
            row + f" {d_eta.mean():+.3f} ± {d_eta.std(ddof=1) / se:.3f} |"
            f" {d_excess.mean():+.3f} ± {d_excess.std(ddof=1) / se:.3f} |"
        )
    columns = ["eta_r", *GROUPS, *MICROSTRUCTURE]
    print(
        "\nBy phase (a pulse's fields apart; means over states of the intervals' means; eta_r by stress"
        " contribution; microstructure at the intervals' ends):\n"
    )
    print("| protocol | phase (Mn_ref) | " + " | ".join(columns) + " |")
    print("|---|---|" + "---|" * len(columns))
    for name, masons in protocols.items():
        per_state = [phase_rows(episodes[f"{name}/{i}"], len(masons), args.skip) for i in range(args.states)]
        for phase, mason in enumerate(masons):
            cells = [np.mean([rows[phase][c] for rows in per_state]) for c in columns]
            label = "off" if math.isinf(mason) else f"{mason:g}"
            if len(masons) > 2:  # a field can recur in a longer pattern: name its place too
                label = f"{phase + 1} of {len(masons)}: {label}"
            print(f"| {name} | {label} | " + " | ".join(f"{v:.3f}" for v in cells) + " |")


def phase_rows(episode: dict, period: int, skip: int) -> list[dict[str, float]]:
    """Per phase ``k`` of a protocol of ``period`` fields (1: steady; 2 or more: a pulse's fields in turn):
    means over the intervals ``i >= skip`` with ``i % period == k`` of eta_r, its contribution groups
    (:data:`GROUPS`) and the recorded microstructure."""
    rows = []
    for phase in range(period):
        picked = [i for i in range(skip, len(episode["eta_r"])) if i % period == phase]
        row = {"eta_r": float(np.mean([episode["eta_r"][i] for i in picked]))}
        for group, names in GROUPS.items():
            row[group] = float(np.mean([sum(episode["contributions"][i][n] for n in names) for i in picked]))
        for name in MICROSTRUCTURE:
            row[name] = float(np.mean([episode[name][i] for i in picked]))
        rows.append(row)
    return rows


if __name__ == "__main__":
    main()
