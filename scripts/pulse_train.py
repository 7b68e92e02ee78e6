"""Does a pulsed field beat a steady one of the same mean energy? Field protocols at a held shear rate.

    python scripts/pulse_train.py --out DIR [--env dipenv/ThickeningControl-v2] [--rate 4] [--states 4]
        [--intervals 16] [--skip 4] [--protocols steady:0.2,pulse:0.1:off,steady:0.1]

The trained PPO policies of the thickening-control study alternate the strongest field with a weak one
or none from one interval to the next at high shear rates (``scripts/field_pulsing.py``). This plays
field protocols in the environment (its physics, start states and reward terms) with the shear rate held
at ``--rate`` (a one-hold ``reset(options={"schedule": ...})``), from the first ``--states`` test start
states, for ``--intervals`` intervals (a truncated episode), and averages each interval's time-averaged
``eta_r``, its excess over the env's cap and the field energy ``<1/Mn_ref>`` over the intervals after the
first ``--skip``. Protocols: ``steady:MN`` (``Mn_ref = MN`` or ``off``) and ``pulse:MN1:MN2`` (MN1 on even
intervals, MN2 on odd ones). The time average covers every instant, so a pulse that lowers it at equal
mean energy does so through the suspension's response (the structure outliving the field), not by how it
is sampled.

Writes ``DIR/episodes.json`` (per protocol and state: per-interval eta_r, energy, Mn_ref), reused on rerun
(resumable, keyed by protocol and state), ``DIR/command.txt``, and a Markdown table on stdout: per
protocol the means over states and, for each protocol after the first, the paired difference to the first
(mean ± standard error over states).
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


def parse_protocol(text: str) -> list[float]:
    """``steady:MN`` -> [MN]; ``pulse:A:B`` -> [A, B] (``off`` -> inf)."""
    kind, *values = text.split(":")
    masons = [math.inf if v == "off" else float(v) for v in values]
    if kind == "steady" and len(masons) == 1 or kind == "pulse" and len(masons) == 2:
        if all(m > 0 for m in masons):
            return masons
    raise ValueError(f"a protocol is steady:MN or pulse:MN1:MN2 with Mn_ref > 0 or 'off', got {text!r}")


def play(env: gym.Env, masons: list[float], index: int, rate: float, intervals: int) -> dict[str, list]:
    unwrapped: Any = env.unwrapped  # a ThickeningControlEnv
    mapping = unwrapped.mapping
    duration = unwrapped.episode_duration + 1.0
    hold = {"times": [0.0, duration], "rates": [rate, rate]}
    env.reset(seed=0, options={"split": "test", "index": index, "schedule": hold})
    out: dict[str, list] = {"eta_r": [], "excess": [], "energy": [], "mason_number": []}
    for k in range(intervals):
        action = np.array([mapping.action_for(masons[k % len(masons)])], dtype=np.float32)
        _, _, terminated, truncated, info = env.step(action)
        if info.get("simulation_failed"):
            raise RuntimeError(f"simulation failed on state {index}, interval {k}")
        out["eta_r"].append(float(info["eta_r"]))
        out["excess"].append(max(0.0, float(info["eta_r"]) - float(info["eta_cap"])))
        out["energy"].append(float(info["field_energy"]))
        m = float(info["mason_number"])
        out["mason_number"].append(m if math.isfinite(m) else "inf")
        if terminated or truncated:
            break
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--env", default="dipenv/ThickeningControl-v2")
    parser.add_argument("--rate", type=float, default=4.0, help="held shear rate (gammadot_ref), > 0")
    parser.add_argument("--states", type=int, default=4, help="first test start states, >= 2")
    parser.add_argument("--intervals", type=int, default=16, help="intervals per episode, > --skip")
    parser.add_argument("--skip", type=int, default=4, help="leading intervals left out of the means, >= 0")
    parser.add_argument("--protocols", default="steady:0.2,pulse:0.1:off,steady:0.1")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.rate) and args.rate > 0):
        parser.error(f"--rate must be a finite number > 0, got {args.rate}")
    if args.states < 2:
        parser.error(f"--states must be >= 2 (paired standard errors), got {args.states}")
    if not 0 <= args.skip < args.intervals:
        parser.error(f"--skip must be in [0, --intervals), got {args.skip} with --intervals {args.intervals}")
    try:
        protocols = {name: parse_protocol(name) for name in args.protocols.split(",")}
    except ValueError as error:
        parser.error(f"--protocols: {error}")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "command.txt").write_text(" ".join([sys.executable, *sys.argv]) + "\n")
    store = args.out / "episodes.json"
    setup = {"env": args.env, "rate": args.rate, "intervals": args.intervals}
    episodes: dict[str, dict] = json.loads(store.read_text()) if store.exists() else {}
    env = gym.make(args.env)
    for name, masons in protocols.items():
        for index in range(args.states):
            key = f"{name}/{index}"
            if key in episodes and episodes[key]["setup"] == setup:
                continue
            episodes[key] = {"setup": setup, **play(env, masons, index, args.rate, args.intervals)}
            tmp = store.with_suffix(".tmp")
            tmp.write_text(json.dumps(episodes))
            tmp.replace(store)
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


if __name__ == "__main__":
    main()
