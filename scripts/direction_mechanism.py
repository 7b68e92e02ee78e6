"""Why the field's direction moves eta_r: the microstructure of the direction map's final states (issue 44).

    python scripts/direction_mechanism.py MAP_ROOT [--phi 0.45] [--seed 1] [--mason 1]
        [--figure results/direction_map/mechanism.png] > results/direction_map/mechanism.md

``MAP_ROOT`` is the direction map's output root (``scripts/direction_map.sh``): one sweep folder
``phi{phi}_{direction}`` per direction, each point folder holding ``final_state.npz`` (the configuration at
the run's last strain). For every direction and Mason number found, the script prints the fabric tensor
``A = <n n>`` of the near pairs (centre distance ``r < 2.2 a``, :func:`sim.fabric_tensor`; isotropic
``I/3``) and the contact number, from the final configuration. The component along the field,
``A_ff = f.A.f``, is the share of near neighbours that sit along the field: well below 1/3 means the
particles gather in sheets normal to the field (induced-charge electrophoresis pushes pairs apart along the
field and together across it; paper §1, Fig. 5).

The figure shows, for the field along y and along z at one Mason number, the pair density on the three
coordinate planes (x–y, x–z, y–z), each from the pairs in a slab ``|d_out| < 1 a`` about the plane, in
units of the ideal-gas density (``g = 1``). One configuration of N = 500 gives about 10^5 pairs, so the
maps are noisy at the bin level (bins of 0.25 a) but their layers and voids span many bins.

A single final configuration per run: the sd of a fabric component over independent configurations of
N = 500 is about 0.01 (about 1,500 near pairs), which the table's differences (0.1-0.2) dwarf.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import sim  # noqa: E402

DIRECTIONS = {
    "y": ("y (gradient)", (0.0, 1.0, 0.0)),
    "z": ("z (vorticity)", (0.0, 0.0, 1.0)),
    "x": ("x (flow)", (1.0, 0.0, 0.0)),
    "ext": ("x+y (extensional)", (1.0, 1.0, 0.0)),
    "comp": ("x-y (compressional)", (1.0, -1.0, 0.0)),
    "yz": ("y+z (45 deg)", (0.0, 1.0, 1.0)),
}
FABRIC_CUTOFF = 2.2  # a: first coordination shell of a phi 0.45 suspension (g(r)'s first minimum ~2.2 a)
CONTACT_GAP = 0.1  # a: surface gap counted as a contact
SLAB = 1.0  # a: half-thickness of the slab about each plane in the g maps
HALF_WIDTH = 5.0  # a: the maps cover -5 a .. 5 a
BINS = 40  # per side (0.25 a)


def final_states(map_root: Path, phi: str, seed: int) -> list[tuple[str, float, Path]]:
    """``(direction key, Mason number, final_state.npz)`` of every finished point, in DIRECTIONS order."""
    found = []
    for key in DIRECTIONS:
        sweep = map_root / f"phi{phi}_{key}"
        if not sweep.is_dir():
            continue
        for point in sorted(sweep.iterdir()):
            state = point / "final_state.npz"
            params = point / "params.json"
            if not (state.is_file() and params.is_file()):
                continue
            config = json.loads(params.read_text())
            config = config.get("config", config)
            if int(config.get("seed", -1)) != seed:
                continue
            found.append((key, float(config["mason_number"]), state))
    found.sort(key=lambda item: (list(DIRECTIONS).index(item[0]), item[1]))
    return found


def load_state(path: Path) -> tuple[np.ndarray, float, float]:
    """Positions (wrapped), box length and strain of a ``final_state.npz``."""
    with np.load(path) as data:
        positions = np.array(data["positions"], dtype=np.float64)
        box_length = float(data["box_length"])
        strain = float(data["strain"])
    box = sim.LeesEdwardsBox(box_length, strain)
    wrapped, _ = box.wrap(positions)
    return wrapped, box_length, strain


def planar_maps(positions: np.ndarray, box_length: float, strain: float) -> dict[str, np.ndarray]:
    """Pair density on the x–y, x–z and y–z planes (slab ``|d_out| < SLAB``), ideal gas = 1.

    All ordered pairs ``i != j`` by minimum image (exact for ``|d| < L/2``; the maps reach ``HALF_WIDTH``
    < L/2). The ideal count per bin is ``N (N-1)/V * bin area * 2 SLAB``.
    """
    n = positions.shape[0]
    box = sim.LeesEdwardsBox(box_length, strain)
    i, j = np.triu_indices(n, k=1)
    d = box.minimum_image(positions[j] - positions[i])
    d = np.concatenate([d, -d])  # ordered pairs
    edges = np.linspace(-HALF_WIDTH, HALF_WIDTH, BINS + 1)
    area = (edges[1] - edges[0]) ** 2
    ideal = n * (n - 1) / box_length**3 * area * 2.0 * SLAB
    maps = {}
    for name, (a, b, out) in {"x-y": (0, 1, 2), "x-z": (0, 2, 1), "y-z": (1, 2, 0)}.items():
        keep = np.abs(d[:, out]) < SLAB
        counts, _, _ = np.histogram2d(d[keep, a], d[keep, b], bins=[edges, edges])
        maps[name] = counts / ideal
    return maps


def fabric_row(key: str, mason: float, path: Path) -> dict[str, float | str]:
    positions, box_length, strain = load_state(path)
    fabric = sim.fabric_tensor(positions, box_length, strain, FABRIC_CUTOFF)
    f = np.asarray(DIRECTIONS[key][1])
    f = f / np.linalg.norm(f)
    return {
        "direction": DIRECTIONS[key][0],
        "mason": mason,
        "A_ff": float(f @ fabric @ f),
        "A_xx": float(fabric[0, 0]),
        "A_yy": float(fabric[1, 1]),
        "A_zz": float(fabric[2, 2]),
        "A_xy": float(fabric[0, 1]),
        "contacts": float(sim.contact_number(positions, box_length, strain, CONTACT_GAP)),
        "strain": strain,
    }


def eta_of(path: Path) -> float:
    result = path.parent / "result.json"
    if not result.is_file():
        return math.nan
    data = json.loads(result.read_text())
    for key in ("eta_r", "relative_viscosity"):
        if key in data:
            value = data[key]
            return float(value["mean"] if isinstance(value, dict) else value)
    return math.nan


def figure(states: dict[str, Path], mason: float, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [key for key in ("y", "z") if key in states]
    fig, axes = plt.subplots(
        len(rows), 3, figsize=(11.5, 3.6 * len(rows)), squeeze=False, layout="constrained"
    )
    image = None
    for r, key in enumerate(rows):
        maps = planar_maps(*load_state(states[key]))
        for c, (name, grid) in enumerate(maps.items()):
            ax = axes[r, c]
            image = ax.imshow(
                grid.T,
                origin="lower",
                extent=(-HALF_WIDTH, HALF_WIDTH, -HALF_WIDTH, HALF_WIDTH),
                vmin=0.0,
                vmax=3.0,
                cmap="magma",
            )
            first, second = name.split("-")
            ax.set_xlabel(f"{first} / a")
            ax.set_ylabel(f"{second} / a")
            ax.set_title(f"field {DIRECTIONS[key][0]}: {name} plane", fontsize=10)
    fig.suptitle(f"Pair density g on the coordinate planes (slab |d| < {SLAB:g} a), phi 0.45, Mn {mason:g}")
    if image is not None:
        fig.colorbar(image, ax=axes, shrink=0.8, label="g (ideal gas = 1)")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0], allow_abbrev=False)
    parser.add_argument("map_root", type=Path)
    parser.add_argument("--phi", default="0.45", help="volume fraction as in the folder names")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--mason", type=float, default=1.0, help="Mason number of the figure")
    parser.add_argument("--figure", type=Path, default=None)
    args = parser.parse_args(argv)
    if not args.map_root.is_dir():
        parser.error(f"map_root: no such folder: {args.map_root}")
    found = final_states(args.map_root, args.phi, args.seed)
    if not found:
        parser.error(f"map_root: no finished points at phi {args.phi}, seed {args.seed} in {args.map_root}")
    print(f"### Fabric of the near pairs (r < {FABRIC_CUTOFF} a), phi = {args.phi}, seed {args.seed}\n")
    print("Final configuration of each run (strain 30). Isotropic: every diagonal component 1/3.")
    print("`A_ff`: the share along the field.\n")
    print("| direction | Mn | eta_r | A_ff | A_xx | A_yy | A_zz | A_xy | contacts |")
    print("|---|---|---|---|---|---|---|---|---|")
    for key, mason, path in found:
        row = fabric_row(key, mason, path)
        print(
            f"| {row['direction']} | {mason:g} | {eta_of(path):.2f} | {row['A_ff']:.3f} | {row['A_xx']:.3f} "
            f"| {row['A_yy']:.3f} | {row['A_zz']:.3f} | {row['A_xy']:+.3f} | {row['contacts']:.2f} |"
        )
    if args.figure is not None:
        states = {key: path for key, mason, path in found if math.isclose(mason, args.mason)}
        figure(states, args.mason, args.figure)
        print(f"\nFigure: {args.figure}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
