"""Poles against equators: where on the contact ring of ``g(x, y)`` the pairs of a run sit (paper Fig. 5).

    python scripts/contact_angles.py RUN_OR_SWEEP [...] [--half-angle 10] [--ring 2.0 2.3] [--md]

For every run folder (a folder with ``pair_distribution.npz``, or a sweep folder holding such folders) the
bins of the shear-plane slab whose centres lie on the contact ring ``ring[0] <= r_xy < ring[1]``
(``2 <= r_xy < 2.24`` is a touching pair inside the slab ``|dz| < a``; see
:mod:`sim.observables.pair_distribution`), and on it:

* ``poles``: the mean ``g_xy`` within ``--half-angle`` degrees of the field axis ``y`` (both ends);
* ``equators``: the same around the flow axis ``x`` (both ends); the slab holds the shear plane, so the
  vorticity equator ``z`` is not in it;
* the ring's maximum: the largest bin of ``g_xy`` on the ring and its angle from the field axis (0: a
  pole, 90: an equator), the quantity the paper's "maximum near the poles / at the equators" names.

All bins of the ring have the same area, so a sector's mean ``g`` is its ideal-gas-normalised pair
density. The field is along ``y`` in every run this reads (it checks ``params.json``). Prints a Markdown
table, one row per run, and with ``--md`` the per-(phi, Mn, mechanism, N) means over seeds.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np


def run_folders(paths: list[Path]) -> list[Path]:
    """The run folders named or held (one level down) by ``paths``, sorted; ValueError naming a path that is
    neither, or when there are none."""
    found: list[Path] = []
    for path in paths:
        if (path / "pair_distribution.npz").is_file():
            found.append(path)
        elif path.is_dir():
            found.extend(sorted(p.parent for p in path.glob("*/pair_distribution.npz")))
        else:
            raise ValueError(f"{path} is neither a run folder nor a sweep folder")
    if not found:
        raise ValueError("no pair_distribution.npz under the paths given")
    return found


def ring_sectors(
    g_xy: np.ndarray, x_edges: np.ndarray, y_edges: np.ndarray, ring: tuple[float, float], half_angle: float
) -> tuple[float, float, float, float]:
    """Mean ``g_xy`` over the ring bins within ``half_angle`` degrees of the ``y`` axis (poles) and of the
    ``x`` axis (equators), the ring's largest bin and that bin's angle from the ``y`` axis in degrees (in
    [0, 90]). ``g_xy[i, j]``: ``x`` bin ``i``, ``y`` bin ``j``."""
    xc = 0.5 * (x_edges[1:] + x_edges[:-1])
    yc = 0.5 * (y_edges[1:] + y_edges[:-1])
    x, y = np.meshgrid(xc, yc, indexing="ij")
    r = np.hypot(x, y)
    on_ring = (r >= ring[0]) & (r < ring[1])
    from_x = np.degrees(np.arctan2(np.abs(y), np.abs(x)))  # 0 on the x axis, 90 on the y axis
    poles = on_ring & (from_x >= 90.0 - half_angle)
    equators = on_ring & (from_x <= half_angle)
    if not poles.any() or not equators.any():
        raise ValueError(f"no bin of the ring {ring} lies in a sector of half-angle {half_angle}")
    on = np.flatnonzero(on_ring)
    peak = on[np.argmax(g_xy.ravel()[on])]
    return (
        float(g_xy[poles].mean()),
        float(g_xy[equators].mean()),
        float(g_xy.ravel()[peak]),
        float(90.0 - from_x.ravel()[peak]),
    )


def measure(folder: Path, ring: tuple[float, float], half_angle: float) -> dict[str, Any]:
    """One run's sector means and its parameters; ValueError naming the folder where its ``params.json`` is
    missing or unreadable or lacks a key read here, or its field is not along ``y``."""
    try:
        params = json.loads((folder / "params.json").read_text())["config"]
        direction = np.asarray(params["field_direction"], dtype=float)
        run = {
            "run": folder.name,
            "phi": params["volume_fraction"],
            "mason": float(params["mason_number"]),  # "inf" (no field) is stored as a string
            "mechanism": params["mechanism"],
            "n": params["n_particles"],
            "seed": params["seed"],
        }
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise ValueError(f"{folder}: no readable params.json with a config ({error!r})") from error
    if not np.allclose(direction / np.linalg.norm(direction), [0.0, 1.0, 0.0]):
        raise ValueError(f"{folder}: the field is along {direction}, not y")
    data = np.load(folder / "pair_distribution.npz")
    poles, equators, peak, peak_angle = ring_sectors(
        data["g_xy"], data["x_edges"], data["y_edges"], ring, half_angle
    )
    return {
        **run,
        "poles": poles,
        "equators": equators,
        "peak": peak,
        "peak_angle": peak_angle,
    }


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], allow_abbrev=False)
    parser.add_argument("paths", nargs="+", type=Path, help="run folders or sweep folders")
    parser.add_argument(
        "--half-angle", type=float, default=10.0, help="sector half-angle, degrees, in (0, 45]"
    )
    parser.add_argument("--ring", type=float, nargs=2, default=(2.0, 2.3), help="contact ring, radii in a")
    parser.add_argument("--md", action="store_true", help="also the means over seeds per point")
    args = parser.parse_args(argv)
    if not 0.0 < args.half_angle <= 45.0:
        parser.error(
            f"--half-angle must lie in (0, 45] degrees (sectors must not overlap), got {args.half_angle}"
        )
    if not 0.0 <= args.ring[0] < args.ring[1]:
        parser.error(f"--ring needs 0 <= inner < outer, got {args.ring}")
    try:
        rows = [measure(f, tuple(args.ring), args.half_angle) for f in run_folders(args.paths)]
    except ValueError as error:  # a path that holds no run, a run without y field, a ring with empty sectors
        parser.error(str(error))
    print(
        f"Contact ring {args.ring[0]} <= r_xy < {args.ring[1]} a in the slab |dz| < a; sectors "
        f"+-{args.half_angle:g} deg"
    )
    print("around the field (poles, y) and the flow (equators, x); g = 1 for an ideal gas.\n")
    print("| run | g, poles | g, equators | ring maximum | its angle from the field |\n|---|---|---|---|---|")
    for row in rows:
        print(
            f"| {row['run']} | {row['poles']:.2f} | {row['equators']:.2f} | {row['peak']:.1f} | "
            f"{row['peak_angle']:.0f} deg |"
        )
    if args.md:
        groups: dict[tuple[Any, ...], list[dict[str, Any]]] = defaultdict(list)
        for row in rows:
            groups[(row["phi"], row["mason"], row["mechanism"], row["n"])].append(row)
        print(
            "\n| phi | Mn | mechanism | N | seeds | g, poles | g, equators | ring maximum's angle from the "
            "field (per seed) |\n|---|---|---|---|---|---|---|---|"
        )
        for (phi, mason, mechanism, n), group in sorted(groups.items()):
            angles = ", ".join(f"{row['peak_angle']:.0f}" for row in group)
            print(
                f"| {phi:g} | {mason:g} | {mechanism} | {n} | {len(group)} | "
                f"{np.mean([r['poles'] for r in group]):.2f} | "
                f"{np.mean([r['equators'] for r in group]):.2f} | "
                f"{angles} deg |"
            )
    return rows


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
