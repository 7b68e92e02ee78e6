"""Environment episodes against N: the box-size study's check of the environments' box (issue 24).

    python scripts/env_box_table.py OPEN_LOOP_DIR [OPEN_LOOP_DIR ...] > results/box_size/env_episodes/table.md

Each OPEN_LOOP_DIR is an ``agents.open_loop`` output folder of ``dipenv/FieldMagnitude-v0`` run with
``--env-kwargs '{"n_particles": N}'`` (one N per folder). Per N and constant Mn: the number of test start
states, and over them the mean ± standard error of the episode's time-averaged eta_r in its first half
(strain 0-6 after the field is switched on) and its second half (6-12, what the environments' metric and
the reward's target see), with N1 and N2 over the second half. Printed as a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np


def mean_se(values: np.ndarray) -> str:
    if values.size < 2:
        return f"{values.mean():.2f}"
    return f"{values.mean():.2f} ± {values.std(ddof=1) / math.sqrt(values.size):.2f}"


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("folders", nargs="+", type=Path)
    rows = []
    for folder in parser.parse_args().folders:
        for path in sorted((folder / "points").glob("*.json")):
            point = json.loads(path.read_text())
            n = int(point["identity"]["env_settings"]["simulation"]["n_particles"])
            halves: list[list[float]] = [[], [], [], []]
            for episode in point["episodes"]:
                trace = episode["trace"]
                eta = np.asarray(trace["eta_r"], dtype=float)
                half = eta.size // 2
                halves[0].append(float(eta[:half].mean()))
                halves[1].append(float(eta[half:].mean()))
                halves[2].append(float(np.mean(trace["n1"][half:])))
                halves[3].append(float(np.mean(trace["n2"][half:])))
            mason = point["mason_number"]
            value = math.inf if mason in (None, "off", "inf") else float(mason)
            rows.append((n, value, len(point["episodes"]), halves))
    print("| N | L/a | Mn | test states | eta_r strain 0-6 | eta_r strain 6-12 | N1 6-12 | N2 6-12 |")
    print("|---|---|---|---|---|---|---|---|")
    for n, mason, count, halves in sorted(rows):
        side = (n * 4.0 / 3.0 * math.pi / 0.45) ** (1.0 / 3.0)
        cells = " | ".join(mean_se(np.array(h)) for h in halves)
        print(f"| {n} | {side:.2f} | {'off' if math.isinf(mason) else f'{mason:g}'} | {count} | {cells} |")


if __name__ == "__main__":
    main()
