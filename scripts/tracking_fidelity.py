"""The viscosity-tracking baselines in two fidelities, point by point: simulator against surrogate (issue 44).

    python scripts/tracking_fidelity.py SIM_DIR SUR_DIR [--out FILE.md]

``SIM_DIR`` and ``SUR_DIR`` are ``python -m agents.tracking`` folders made by the same command, on a simulator
id (``dipenv/ViscosityTracking-v0``) and on its surrogate (``dipenv/ViscosityTrackingSurrogate-v0``):
``scripts/tracking_study.sh fidelity`` makes the second from the first's command. No episode is played here:
the script reads what the two folders hold. It refuses (exit 2, naming the argument) a folder that is not an
``agents.tracking`` folder (its ``manifest.json``), and two folders whose tuning split and states, split and
states, schedules file, controllers or grids differ, or whose episodes differ in length, interval, rate
schedules, targets, action map or reward (``env_settings`` of their files): the same start state, rate
schedule and target must be played in both. A grid point one folder lacks (an unfinished command) is
refused too.

**Numbers.** Per grid point of ``tuning/*.json`` (played on the tuning split's states): the mean return and
the mean ``|eta_r - target|`` (the mean over intervals, per episode) in each fidelity, each state's
realisations averaged first (:func:`agents.repeats.per_state`; the simulator folder usually holds one
realisation per state, the surrogate's may hold several samples), then the mean over the states; the
difference is surrogate minus simulator. Then the rank correlations (Spearman's rho and Kendall's tau-b,
``scipy.stats``) between the fidelities of the points' mean returns and of their mean ``|error|``, over
every grid point and per controller with at least 3 points: 1 when the surrogate orders the points as the
simulator does, so that tuning on the surrogate would pick the simulator's order. Then, per controller,
the point each fidelity chose (``tuning.csv``'s ``chosen``: the highest mean return) and whether it is the
same. Last, the rows of ``points/*.json`` held by both folders (the tuned controllers, each at its own
fidelity's chosen point, and trained runs per seed) on ``--split``, with the same two metrics.

Caveats: the simulator's one realisation per state carries the noise of a chaotic trajectory (a
``ViscosityTracking-v0`` row's 8-episode mean is not known better than a few units of return), so a rank
correlation below 1 can be the simulator's noise as much as the surrogate's error; with few points (the
study's 6 constants, 3 feed-forwards, 4 PIs) a rank correlation is coarse. ``--out FILE.md`` writes the
table there and the numbers to ``FILE.json``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from agents.folders import write_text_atomic  # noqa: E402
from agents.repeats import per_state  # noqa: E402
from agents.usage import usage_error  # noqa: E402

PROG = "scripts/tracking_fidelity.py"
COMMAND = "agents.tracking"
FIDELITIES = ("simulator", "surrogate")
"""The two folders' roles, in the order of the arguments (``SIM_DIR``, ``SUR_DIR``)."""
ARGUMENTS = {"simulator": "SIM_DIR", "surrogate": "SUR_DIR"}
EPISODE_KEYS = ("tune_split", "tune_episodes", "split", "episodes", "schedules")
"""Identity entries (``manifest.json`` ``params``) that say which episodes were played: they must agree."""
EPISODE_SETTINGS = (
    "n_particles",
    "volume_fraction",
    "control_interval",
    "episode_steps",
    "mason_min",
    "mason_max",
    "off_band",
    "reward",
    "schedule",
    "target",
)
"""``env_settings`` entries that shape an episode's start, rates, targets, action map and reward (not its
dynamics): they must agree. ``n_particles`` and ``volume_fraction`` sit in the simulator's ``simulation``."""
METRICS = ("return", "mean_abs_error")
"""The per-episode metrics compared."""
MIN_POINTS = 3
"""Fewest points for a per-controller rank correlation."""


class FidelityError(ValueError):
    """Two folders that cannot be compared; the message names the argument."""


def read_json(path: Path, argument: str) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise FidelityError(f"{argument} {path.parent}: {path.name} cannot be read ({error})") from None


def read_folder(folder: Path, argument: str) -> dict[str, Any]:
    """The identity (``manifest.json`` ``params``) of an ``agents.tracking`` folder; ``FidelityError`` naming
    ``argument`` for anything else."""
    manifest = folder / "manifest.json"
    if not manifest.is_file():
        raise FidelityError(
            f"{argument} {folder}: no manifest.json: not a python -m agents.tracking output folder"
        )
    data = read_json(manifest, argument)
    if (
        not isinstance(data, dict)
        or data.get("command") != COMMAND
        or not isinstance(data.get("params"), dict)
    ):
        command = data.get("command") if isinstance(data, dict) else None
        raise FidelityError(
            f"{argument} {folder}: its manifest.json is not {COMMAND}'s (command {command!r}): not a "
            "python -m agents.tracking output folder"
        )
    params: dict[str, Any] = data["params"]
    return params


def check_identities(identities: dict[str, dict[str, Any]]) -> list[str]:
    """The controllers both folders tuned (sorted); ``FidelityError`` naming ``SUR_DIR`` where the episodes,
    the controllers or a grid differ from ``SIM_DIR``'s."""
    sim, sur = identities["simulator"], identities["surrogate"]
    problems = [
        f"{key} {sur.get(key)!r} (SIM_DIR: {sim.get(key)!r})"
        for key in EPISODE_KEYS
        if sim.get(key) != sur.get(key)
    ]
    kinds = {
        f: sorted(k[len("controller_") :] for k in i if k.startswith("controller_"))
        for f, i in identities.items()
    }
    if kinds["simulator"] != kinds["surrogate"]:
        problems.append(f"controllers {kinds['surrogate']} (SIM_DIR: {kinds['simulator']})")
    for kind in sorted(set(kinds["simulator"]) & set(kinds["surrogate"])):
        a, b = sim[f"controller_{kind}"], sur[f"controller_{kind}"]
        if a != b:
            problems.append(
                f"{kind}'s grid {json.dumps(b, sort_keys=True)} (SIM_DIR: {json.dumps(a, sort_keys=True)})"
            )
    if problems:
        raise FidelityError(
            "SUR_DIR: not played on SIM_DIR's episodes and grids (rerun SIM_DIR's command with the "
            "surrogate's --env): it has " + "; ".join(problems)
        )
    return kinds["simulator"]


def episode_settings(settings: dict[str, Any]) -> dict[str, Any]:
    """The :data:`EPISODE_SETTINGS` of an ``env_settings`` (either fidelity's layout)."""
    simulation = settings.get("simulation") or {}
    return {k: settings.get(k, simulation.get(k)) for k in EPISODE_SETTINGS}


def metric_means(record: dict[str, Any], argument: str, path: Path, count: int) -> dict[str, Any]:
    """Mean return and ``|error|`` of a record's first ``count`` states (each state's realisations averaged
    first), and its states and realisations; ``FidelityError`` when a state is missing."""
    episodes = [e for e in record.get("episodes", []) if int(e["index"]) < count]
    states = sorted({int(e["index"]) for e in episodes})
    if states != list(range(count)):
        raise FidelityError(
            f"{argument}: {path} holds states {states}, not 0-{count - 1}: its command has not finished "
            "(rerun it: it resumes)"
        )
    out: dict[str, Any] = {m: float(np.mean(per_state(episodes, m)[1])) for m in METRICS}
    per = [sum(1 for e in episodes if int(e["index"]) == s) for s in states]
    out.update(states=len(states), realisations=[min(per), max(per)])
    return out


def read_records(
    folder: Path, argument: str, sub: str, count: int
) -> tuple[dict[str, dict[str, Any]], dict[str, Any] | None]:
    """Per file of ``folder/sub`` (label -> its metrics, controller, params, settings), and the episode
    settings of the first file."""
    records: dict[str, dict[str, Any]] = {}
    settings = None
    for path in sorted((folder / sub).glob("*.json")):
        record = read_json(path, argument)
        if not isinstance(record, dict) or not isinstance(record.get("episodes"), list):
            raise FidelityError(f"{argument}: {path} is not an agents.tracking record (no episodes)")
        env_settings = (record.get("identity") or {}).get("env_settings")
        if settings is None and isinstance(env_settings, dict):
            settings = episode_settings(env_settings)
        records[path.stem] = {
            "controller": record.get("controller"),
            "params": record.get("params"),
            "name": record.get("name", path.stem),
            **metric_means(record, argument, path, count),
        }
    return records, settings


def chosen_points(folder: Path, argument: str) -> dict[str, str]:
    """Per controller, the point ``tuning.csv`` marks ``chosen``."""
    path = folder / "tuning.csv"
    if not path.is_file():
        return {}
    try:
        with open(path, newline="") as handle:
            return {
                row["controller"]: row["point"] for row in csv.DictReader(handle) if row["chosen"] == "yes"
            }
    except (OSError, KeyError, csv.Error) as error:
        raise FidelityError(f"{argument} {folder}: tuning.csv cannot be read ({error})") from None


def rank_correlations(a: list[float], b: list[float]) -> dict[str, float]:
    """Spearman's rho and Kendall's tau-b of ``a`` and ``b`` (NaN with fewer than 2 points, a constant or
    a NaN)."""
    if len(a) < 2 or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return {"spearman": math.nan, "kendall": math.nan, "points": len(a)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a constant input: NaN, said in the table
        rho = float(stats.spearmanr(a, b).statistic)
        tau = float(stats.kendalltau(a, b).statistic)
    return {"spearman": rho, "kendall": tau, "points": len(a)}


def compare(sim_dir: Path, sur_dir: Path) -> dict[str, Any]:
    """The numbers of the module docstring; ``FidelityError`` naming the argument for folders that cannot be
    compared."""
    folders = dict(zip(FIDELITIES, (sim_dir, sur_dir), strict=True))
    identities = {f: read_folder(folder, ARGUMENTS[f]) for f, folder in folders.items()}
    kinds = check_identities(identities)
    tune_n, n = int(identities["simulator"]["tune_episodes"]), int(identities["simulator"]["episodes"])
    tuning, points, settings = {}, {}, {}
    for f, folder in folders.items():
        tuning[f], tune_settings = read_records(folder, ARGUMENTS[f], "tuning", tune_n)
        points[f], point_settings = read_records(folder, ARGUMENTS[f], "points", n)
        settings[f] = tune_settings or point_settings
    if settings["simulator"] and settings["surrogate"] and settings["simulator"] != settings["surrogate"]:
        sim, sur = settings["simulator"], settings["surrogate"]
        differ = [k for k in EPISODE_SETTINGS if sim[k] != sur[k]]
        shown = "; ".join(f"{k} {sur[k]!r} (SIM_DIR: {sim[k]!r})" for k in differ)
        raise FidelityError(
            f"SUR_DIR {sur_dir}: its episodes are not SIM_DIR's (env_settings of their files): it has {shown}"
        )
    for f, other in (("simulator", "surrogate"), ("surrogate", "simulator")):
        absent = sorted(set(tuning[other]) - set(tuning[f]))
        if absent:
            raise FidelityError(
                f"{ARGUMENTS[f]} {folders[f]}: no tuning/{absent[0]}.json ({len(absent)} grid points "
                "missing): its command has not finished (rerun it: it resumes)"
            )
    order = {kind: k for k, kind in enumerate(kinds)}
    labels = sorted(
        tuning["simulator"], key=lambda p: (order.get(tuning["simulator"][p]["controller"], -1), p)
    )
    rows = []
    for label in labels:
        sim, sur = tuning["simulator"][label], tuning["surrogate"][label]
        rows.append(
            {
                "controller": sim["controller"],
                "point": label,
                "params": sim["params"],
                "simulator": {k: sim[k] for k in (*METRICS, "states", "realisations")},
                "surrogate": {k: sur[k] for k in (*METRICS, "states", "realisations")},
                "difference": {m: sur[m] - sim[m] for m in METRICS},
            }
        )

    def correlations(selected: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
        return {
            m: rank_correlations([r["simulator"][m] for r in selected], [r["surrogate"][m] for r in selected])
            for m in METRICS
        }

    chosen = {f: chosen_points(folder, ARGUMENTS[f]) for f, folder in folders.items()}
    tuned = {
        kind: {
            "simulator": chosen["simulator"].get(kind),
            "surrogate": chosen["surrogate"].get(kind),
            "same": chosen["simulator"].get(kind) is not None
            and chosen["simulator"].get(kind) == chosen["surrogate"].get(kind),
        }
        for kind in kinds
    }
    shared = sorted(set(points["simulator"]) & set(points["surrogate"]))
    played = []
    for label in shared:
        sim, sur = points["simulator"][label], points["surrogate"][label]
        played.append(
            {
                "row": label,
                "simulator": {k: sim[k] for k in (*METRICS, "states", "realisations", "name", "params")},
                "surrogate": {k: sur[k] for k in (*METRICS, "states", "realisations", "name", "params")},
                "difference": {m: sur[m] - sim[m] for m in METRICS},
            }
        )
    return {
        "sim_dir": str(sim_dir),
        "sur_dir": str(sur_dir),
        "env_id": {f: identities[f]["env_id"] for f in FIDELITIES},
        "env_kwargs": {f: identities[f].get("env_kwargs") for f in FIDELITIES},
        "surrogate_model": identities["surrogate"].get("surrogate"),
        "tune_split": identities["simulator"]["tune_split"],
        "tune_episodes": tune_n,
        "split": identities["simulator"]["split"],
        "episodes": n,
        "tuning": rows,
        "correlations": {
            "all": correlations(rows),
            **{
                kind: correlations(selected)
                for kind in kinds
                if len(selected := [r for r in rows if r["controller"] == kind]) >= MIN_POINTS
            },
        },
        "chosen": tuned,
        "rows": played,
        "rows_only_in": {
            f: sorted(set(points[f]) - set(shared)) for f in FIDELITIES if set(points[f]) - set(shared)
        },
    }


def _number(value: float, spec: str) -> str:
    return "n/a" if not math.isfinite(value) else format(value, spec)


def _realisations(entry: dict[str, Any]) -> str:
    low, high = entry["realisations"]
    return f"{entry['states']}x{low}" if low == high else f"{entry['states']}x{low}-{high}"


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    return [
        "| " + " | ".join(header) + " |",
        "|" + "---|" * len(header),
        *("| " + " | ".join(row) + " |" for row in rows),
    ]


def _metric_cells(row: dict[str, Any]) -> list[str]:
    """Return sim, sur, difference; mean abs error sim, sur, difference."""
    sim, sur, diff = row["simulator"], row["surrogate"], row["difference"]
    return [
        _number(sim["return"], ".2f"),
        _number(sur["return"], ".2f"),
        _number(diff["return"], "+.2f"),
        _number(sim["mean_abs_error"], ".3f"),
        _number(sur["mean_abs_error"], ".3f"),
        _number(diff["mean_abs_error"], "+.3f"),
    ]


METRIC_HEADER = [
    "return sim",
    "return sur",
    "difference",
    "mean abs error sim",
    "mean abs error sur",
    "difference",
]


def markdown(result: dict[str, Any]) -> str:
    """The tables of the module docstring."""
    model = result.get("surrogate_model")
    lines = [
        f"Simulator `{result['sim_dir']}` ({result['env_id']['simulator']}) against surrogate "
        f"`{result['sur_dir']}` ({result['env_id']['surrogate']}"
        + (f", model {model['kind']} {model['digest']}" if model else "")
        + f"). Grid points on the first {result['tune_episodes']} states of {result['tune_split']}; "
        "episodes: states x realisations; each state's realisations averaged first; difference: surrogate "
        "minus simulator.",
        "",
        *_table(
            ["controller", "point", *METRIC_HEADER, "episodes sim", "episodes sur"],
            [
                [
                    str(row["controller"]),
                    row["point"],
                    *_metric_cells(row),
                    _realisations(row["simulator"]),
                    _realisations(row["surrogate"]),
                ]
                for row in result["tuning"]
            ],
        ),
        "",
        "Rank correlations of the points' means across the fidelities:",
        "",
    ]
    correlations = []
    for group, values in result["correlations"].items():
        r, e = values["return"], values["mean_abs_error"]
        name = "every grid point" if group == "all" else group
        numbers = [_number(x[k], ".2f") for x in (r, e) for k in ("spearman", "kendall")]
        correlations.append([name, str(r["points"]), *numbers])
    header = ["points", "n", "return Spearman", "return Kendall", "abs error Spearman", "abs error Kendall"]
    lines += _table(header, correlations)
    lines += ["", "The tuned point (tuning.csv's chosen):", ""]
    picks = [
        [kind, pick["simulator"] or "-", pick["surrogate"] or "-", "yes" if pick["same"] else "no"]
        for kind, pick in result["chosen"].items()
    ]
    lines += _table(["controller", "simulator", "surrogate", "same"], picks)
    if result["rows"]:
        lines += [
            "",
            f"Rows played on the first {result['episodes']} states of {result['split']} (points/*.json held "
            "by both; a tuned controller at each fidelity's own chosen point):",
            "",
        ]
        played = []
        for row in result["rows"]:
            a, b = row["simulator"]["name"], row["surrogate"]["name"]
            played.append([row["row"], a if a == b else f"{a} / {b}", *_metric_cells(row)])
        lines += _table(["row", "played (sim / sur)", *METRIC_HEADER], played)
    for f, labels in result["rows_only_in"].items():
        lines += ["", f"Rows only in {ARGUMENTS[f]} (not compared): {', '.join(labels)}."]
    return "\n".join(lines) + "\n"


def _json_ready(value: Any) -> Any:
    """NaN as null (strict JSON)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json_ready(v) for v in value]
    return value


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("sim_dir", metavar="SIM_DIR", type=Path, help="agents.tracking folder, simulator id")
    parser.add_argument("sur_dir", metavar="SUR_DIR", type=Path, help="the same command's, surrogate id")
    parser.add_argument(
        "--out", type=Path, default=None, metavar="FILE.md", help="also write the table and FILE.json"
    )
    args = parser.parse_args(argv)
    for argument, folder in (("SIM_DIR", args.sim_dir), ("SUR_DIR", args.sur_dir)):
        if not folder.is_dir():
            usage_error(PROG, f"{argument} {folder}: no such folder (an agents.tracking output folder)")
    if args.sim_dir.resolve() == args.sur_dir.resolve():
        usage_error(
            PROG, f"SUR_DIR {args.sur_dir} is SIM_DIR: give the simulator's folder and the surrogate's"
        )
    if args.out is not None and args.out.suffix != ".md":
        usage_error(
            PROG, f"--out {args.out}: a Markdown file name (FILE.md; the numbers go to FILE.json beside it)"
        )
    try:
        result = compare(args.sim_dir, args.sur_dir)
    except FidelityError as error:
        usage_error(PROG, str(error))
    table = markdown(result)
    print(table, end="")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(args.out, table)
        write_text_atomic(args.out.with_suffix(".json"), json.dumps(_json_ready(result), indent=1) + "\n")
    return result


if __name__ == "__main__":
    main()
