"""Closed-loop check of surrogate models against stored simulator episodes of the validation split.

    python scripts/surrogate_stored_rows.py MODEL.npz [MODEL.npz ...] [--samples 16] [--out FILE.md]
        [--controllers results/thickening_control/v2/feedforward results/thickening_control/v2/pulse]
        [--runs results/thickening_control/v2/rl/ppo/seed0 ...]

No simulation: every row already played the 8 validation episodes of ``ThickeningControl-v2`` (one
realisation each). The tuned controllers' grid points were stored by ``agents.controllers``
(``DIR/tuning/*.json``: feed-forward ``Mn*`` and pulse ``(rate_on, mason_steady)``), and the PPO runs
stored their validation returns at the end of training (``RUN/eval/evaluations.npz``, last row: the
final policy, mean action, in the training physics, whose return bias is +2.4 +- 2.8;
docs/thickening_control.md#coarse-training). Each model plays every row closed loop on the same 8
episodes (``--samples`` each, seeds ``45_000_000 + 100 k + j``). The table gives the rows' mean returns
in both fidelities and the Spearman rank correlation between them.

Caveats: one simulator realisation per episode (a row's 8-episode mean carries a noise sd of about 5),
and each controller's tuning picked its grid point on these episodes, so the picked point's simulator
return is biased upward (the winner's curse). Only the validation split is read: the test and fresh
splits stay untouched.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
V2 = "results/thickening_control/v2"
CONTROLLERS = (f"{V2}/feedforward", f"{V2}/pulse")
RUNS = tuple(f"{V2}/rl/ppo/seed{s}" for s in range(5))
SEED = 45_000_000


def _check_module() -> Any:
    spec = importlib.util.spec_from_file_location("surrogate_check", ROOT / "scripts" / "surrogate_check.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def stored_rows(controllers: list[Path], runs: list[Path]) -> dict[str, dict[int, float]]:
    """Row spec (``scripts/surrogate_check.py``'s syntax) -> {validation index: simulator return}."""
    rows: dict[str, dict[int, float]] = {}
    for folder in controllers:
        for path in sorted((folder / "tuning").glob("*.json")):
            data = json.loads(path.read_text())
            p = data["params"]
            if data["controller"] == "feedforward":
                row = f"feedforward:{p['mason_star']:g}"
            elif data["controller"] == "pulse":
                row = f"pulse:{p['rate_on']:g}:{p['mason_steady']:g}"
            else:
                continue
            rows[row] = {
                int(e["index"]): float(e["return"])
                for e in data["episodes"]
                if e.get("realisation", 0) == 0 and e["split"] == "validation"
            }
    for run in runs:
        returns = np.load(run / "eval" / "evaluations.npz")["results"][-1]
        rows[f"ppo:{run}"] = {k: float(r) for k, r in enumerate(returns)}
    return rows


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0], allow_abbrev=False)
    parser.add_argument("models", nargs="+", type=Path)
    parser.add_argument("--controllers", nargs="*", type=Path, default=[ROOT / c for c in CONTROLLERS])
    parser.add_argument("--runs", nargs="*", type=Path, default=[ROOT / r for r in RUNS])
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--out", type=Path, default=None, help="also write the table (Markdown) and JSON")
    args = parser.parse_args(argv)
    check = _check_module()
    rows = stored_rows(args.controllers, args.runs)
    results: dict[str, Any] = {"rows": {}, "spearman": {}}
    for row, simulated in rows.items():
        results["rows"][row] = {
            "simulator": float(np.mean(list(simulated.values()))),
            "episodes": len(simulated),
        }
    for model in args.models:
        name = model.name
        for row, simulated in rows.items():
            env = check.surrogate_env("dipenv/ThickeningControl-v2", model, check.row_env_kwargs(row))
            policy, reset = check.make_policy(row, env)
            means = []
            for k in simulated:
                options = {"split": "validation", "index": k}
                plays = [
                    check.play(env, policy, reset, SEED + 100 * k + j, options) for j in range(args.samples)
                ]
                means.append(np.mean([sum(p["reward"]) for p in plays]))
            results["rows"][row][name] = float(np.mean(means))
            env.close()
            print(json.dumps({"model": name, "row": row, **results["rows"][row]}))
            sys.stdout.flush()
        names = list(rows)
        results["spearman"][name] = float(
            stats.spearmanr(
                [results["rows"][r]["simulator"] for r in names], [results["rows"][r][name] for r in names]
            ).statistic
        )
    header = "| row | simulator | " + " | ".join(m.name for m in args.models) + " |"
    lines = [header, "|---" * (2 + len(args.models)) + "|"]
    for row, values in results["rows"].items():
        label = row.replace(str(ROOT) + "/", "")
        cells = " | ".join(f"{values[m.name]:.1f}" for m in args.models)
        lines.append(f"| {label} | {values['simulator']:.1f} | {cells} |")
    lines.append(
        "| Spearman with the simulator | | "
        + " | ".join(f"{results['spearman'][m.name]:.2f}" for m in args.models)
        + " |"
    )
    table = "\n".join(lines)
    print(table)
    if args.out is not None:
        args.out.write_text(table + "\n")
        args.out.with_suffix(".json").write_text(json.dumps(results, indent=1) + "\n")
    return results


if __name__ == "__main__":
    main()
