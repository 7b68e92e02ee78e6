"""DEP + shear at phi = 15% (paper Fig. 2b): eta_r against Mn, with dielectrophoresis alone and with the full
dipolophoresis, as a Markdown table and a figure.

    python scripts/dep_shear_table.py DEP_SWEEP [DEP_SWEEP ...] --dip results/paper_grid [--plot FILE.png]

Reads every ``result.json`` one level under each ``DEP_SWEEP`` (``sim sweep --mechanism dep``; the points are
grouped by N and Mn and averaged over seeds) and, with ``--dip``, the phi = 0.15 points of a sweep of the full
dipolophoresis (the paper grid; its no-field point gives the pure-shear reference). Columns: eta_r (seed mean,
and the seed range or the one seed's block standard error), the excess over pure shear, N1, N2 (in
``eta gammadot``), the fabric tensor's field (``A_yy``), vorticity (``A_zz``) and shear (``A_xy``) components
and the contacts per particle (:mod:`sim.observables`), and the local slope ``d ln(excess) / d ln Mn``
between neighbouring Mn where both excesses are at least 0.05 (the power of an electrorheological fluid's
``eta - eta_inf ~ Mn^-s``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

PHI = 0.15


def points(folder: Path, mechanism: str) -> dict[tuple[int, float], list[dict[str, Any]]]:
    """The phi = 0.15 results of ``mechanism`` under ``folder``, grouped by (N, Mn); Mn = inf for no field.
    ValueError naming a ``result.json`` that is unreadable or lacks the keys read here."""
    grouped: dict[tuple[int, float], list[dict[str, Any]]] = defaultdict(list)
    for path in sorted(folder.glob("*/result.json")):
        try:
            result = json.loads(path.read_text())
            mason = float(result["mason_number"])
            phi, n = float(result["volume_fraction"]), int(result["n_particles"])
            its_mechanism = result["mechanism"]
        except (OSError, ValueError, KeyError, TypeError) as error:
            raise ValueError(f"{path}: not a readable sim result ({error!r})") from error
        if abs(phi - PHI) > 1e-9:
            continue
        if its_mechanism != mechanism and math.isfinite(mason):
            continue
        grouped[(n, mason)].append(result)
    return grouped


def row(results: list[dict[str, Any]]) -> dict[str, Any]:
    """Seed means of one point."""
    eta = [r["relative_viscosity"] for r in results]
    fabric = np.mean([np.asarray(r["fabric_tensor"]) for r in results], axis=0)
    spread = (
        f"{min(eta):.2f}-{max(eta):.2f}"
        if len(eta) > 1
        else f"+- {results[0]['relative_viscosity_stderr']:.3f}"
    )
    return {
        "seeds": len(eta),
        "eta_r": float(np.mean(eta)),
        "spread": spread,
        "n1": float(np.mean([r["n1"] for r in results])),
        "n2": float(np.mean([r["n2"] for r in results])),
        "a_yy": float(fabric[1, 1]),
        "a_zz": float(fabric[2, 2]),
        "a_xy": float(fabric[0, 1]),
        "contacts": float(np.mean([r["contact_number"] for r in results])),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], allow_abbrev=False)
    parser.add_argument("sweeps", nargs="+", type=Path, help="sweep folders of --mechanism dep runs")
    parser.add_argument(
        "--dip", type=Path, required=True, help="a sweep of the full DIP with phi 0.15 points"
    )
    parser.add_argument("--plot", type=Path, help="write eta_r against Mn here")
    args = parser.parse_args(argv)
    dep: dict[tuple[int, float], list[dict[str, Any]]] = defaultdict(list)
    try:
        for sweep in args.sweeps:
            for key, results in points(sweep, "dep").items():
                dep[key].extend(results)
        dip = points(args.dip, "dip")
    except ValueError as error:
        parser.error(str(error))
    if not dep:
        parser.error(f"no phi = {PHI} DEP results under {[str(s) for s in args.sweeps]}")
    pure = [r for (n, mason), results in dip.items() if math.isinf(mason) for r in results]
    if not pure:
        parser.error(f"{args.dip} holds no phi = {PHI} point without a field (the pure-shear reference)")
    eta_inf = float(np.mean([r["relative_viscosity"] for r in pure]))
    print(
        f"DEP + shear at phi = {PHI}; pure shear (no field, {args.dip}, {len(pure)} runs): "
        f"eta_r = {eta_inf:.3f}."
    )
    print("eta_r and N1, N2 in eta gammadot; A: fabric tensor; slope: -d ln(eta_r - eta_inf)/d ln Mn to the")
    print("next Mn.\n")
    print(
        "| N | Mn | seeds | eta_r | seed range / s.e. | excess | N1 | N2 | A_yy | A_zz | A_xy | contacts | "
        "slope | eta_r, DIP (N = 100) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    )
    series: dict[int, list[tuple[float, float]]] = defaultdict(list)
    for n in sorted({n for n, _ in dep}):
        masons = sorted(m for (k, m) in dep if k == n)
        rows = [row(dep[(n, m)]) for m in masons]
        for i, (mason, r) in enumerate(zip(masons, rows, strict=True)):
            excess = r["eta_r"] - eta_inf
            series[n].append((mason, r["eta_r"]))
            slope = ""
            if i + 1 < len(masons):
                following = rows[i + 1]["eta_r"] - eta_inf
                if excess >= 0.05 and following >= 0.05:  # below, the excess is within a few s.e. of 0
                    slope = f"{-math.log(following / excess) / math.log(masons[i + 1] / mason):.2f}"
            dip_here = dip.get((100, mason))
            dip_text = f"{np.mean([d['relative_viscosity'] for d in dip_here]):.2f}" if dip_here else ""
            print(
                f"| {n} | {mason:g} | {r['seeds']} | {r['eta_r']:.2f} | {r['spread']} | {excess:.2f} | "
                f"{r['n1']:.3f} | {r['n2']:.3f} | {r['a_yy']:.2f} | {r['a_zz']:.2f} | {r['a_xy']:.3f} | "
                f"{r['contacts']:.2f} | {slope} | {dip_text} |"
            )
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(5.5, 4.0))
        for n, values in sorted(series.items()):
            ax.plot(*zip(*values, strict=True), "o-", label=f"DEP alone, N = {n}")
        dip_values = sorted(
            (m, float(np.mean([d["relative_viscosity"] for d in r])))
            for (n, m), r in dip.items()
            if n == 100 and math.isfinite(m)
        )
        if dip_values:
            ax.plot(*zip(*dip_values, strict=True), "s--", color="grey", label="DIP (ICEP + DEP), N = 100")
        ax.axhline(eta_inf, color="k", lw=0.8, ls=":", label="no field")
        ax.set_xscale("log")
        ax.set_xlabel("Mn")
        ax.set_ylabel("eta_r")
        ax.set_title(f"DEP + shear, phi = {PHI} (paper Fig. 2b)")
        ax.legend(frameon=False)
        fig.tight_layout()
        args.plot.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.plot, dpi=150)
        print(f"\nfigure: {args.plot}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
