"""Open-loop baseline: constant fields through the same evaluation path as the learned policies.

    python -m agents.open_loop --env dipenv/FieldMagnitude-v0 --out runs/open_loop
        [--mason off,20,5,2,1,0.5,0.2,0.1,0.05] [--directions y,x,z,xy] [--split test] [--episodes N]
        [--repeats K] [--schedules FILE] [--env-kwargs JSON] [--workers 2] [--scheduler ADDRESS]
        [--resume | --overwrite]

Every point (a constant Mason number, and a direction for the vector env) runs ``--repeats`` episodes
(realisations 0 .. K-1 of :mod:`dipenv.realisations`; default one, the stored state itself) from each of
the first ``--episodes`` start states of ``--split`` and writes ``DIR/points/<label>.json`` (the
episodes' metrics and traces, written after every episode); a rerun reuses the episodes already written
for the same env, arguments and start-state library and plays only the missing ones, so the command is
resumable and a rerun with a larger ``--repeats`` adds realisations to the stored ones. Statistics average
a state's realisations first (:mod:`agents.repeats`); intervals are over states.
``--schedules FILE`` (the thickening-control envs) plays the file's schedules instead of the split's own:
episode ``j`` follows schedule ``j`` from its start state of ``--split`` (:mod:`agents.schedules`);
``--episodes N`` then takes the first N entries, and the statistics run over the entries.
Then it writes ``pareto.csv`` / ``pareto.json``
(per point: mean ``eta_r`` over the second half of the episodes with its 95% interval over start
states, field energy ``<1/Mn>``, return, and whether the point is on the Pareto front of low ``eta_r``
and low energy), ``best_constant.json`` (the point with the highest mean return: the best constant
policy for the reward in use, chosen on the same start states, which favours the baseline) and
``pareto.png``, over every point of the folder that belongs to the same study (same env, split, states
and library; each with the realisations it holds). The stored points keep every interval's ``eta_r``
and field energy, so a rerun with another reward (``target_viscosity`` or ``energy_weight`` in
``--env-kwargs``, or a changed default) rescores them without simulating again.

The folder follows the run-folder protocol (:mod:`agents.folders`): it is claimed, with ``manifest.json``
written first, after the arguments are checked and before any start state is made; its identity is the
env id, its arguments less the reward's (``target_viscosity`` and ``energy_weight``: rescored), the
split and the number of start states (with ``--schedules``, the number of entries and the file's digest).
The Mason numbers, directions and ``--repeats`` are not part of it (a
rerun adds points and realisations to the study). Another command's folder, or one of other parameters, is
refused (exit 2) unless ``--overwrite`` deletes the whole previous run; a folder made before manifests (it
holds ``pareto.json``, ``best_constant.json`` or an ``agents.open_loop`` ``command.txt``) is adopted when its
points were made with the same parameters.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from agents.folders import (
    add_folder_options,
    claim_out,
    command_line,
    legacy_conflict,
    legacy_markers,
    save_figure,
    write_command,
    write_text_atomic,
)
from agents.repeats import episode_key, missing, per_state, select
from agents.rollout import constant_policy, library_key, make_env, run_episode
from agents.schedules import (
    ScheduleSet,
    episode_count,
    episodes_payload,
    load_schedules,
    matches,
    play,
    prepare_states,
)
from agents.statistics import interval_estimates
from agents.tasks import run_tasks
from agents.usage import (
    checked_env,
    compile_notice,
    directory,
    integer_at_least,
    json_object,
    output_directory,
    scheduler_address,
    split_size,
    usage_error,
)

PROG = "python -m agents.open_loop"

DIRECTIONS = {"y": (0.0, 1.0, 0.0), "x": (1.0, 0.0, 0.0), "z": (0.0, 0.0, 1.0), "xy": (1.0, 1.0, 0.0)}
"""Named directions for ``--directions`` (``xy``: 45 degrees in the shear plane)."""

RESCORED_KWARGS = ("target_viscosity", "energy_weight")
"""Environment arguments that only change the reward: stored points are rescored, not rerun, for them."""

DEFAULT_MASON = ("off", 20.0, 5.0, 2.0, 1.0, 0.5, 0.2, 0.1, 0.05)


def point_label(mason: float, direction: str | None) -> str:
    base = "off" if math.isinf(mason) else f"Mn{mason:g}"
    return base if direction is None else f"{base}_e{direction}"


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value)}")


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` as JSON (non-finite floats as strings), atomically."""
    write_text_atomic(path, json.dumps(_finite(data), indent=1, default=_json_default))


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def read_json(path: Path) -> Any:
    def floats(obj: Any) -> Any:
        if isinstance(obj, str) and obj in ("inf", "-inf", "nan"):
            return float(obj)
        if isinstance(obj, dict):
            return {k: floats(v) for k, v in obj.items()}
        if isinstance(obj, list):
            return [floats(v) for v in obj]
        return obj

    return floats(json.loads(path.read_text()))


def constant_action(unwrapped: Any, mason: float, direction: str | None) -> list[float]:
    """The action that holds ``mason`` (inf: off) in ``unwrapped``'s mapping, with the named direction
    (a key of :data:`DIRECTIONS`) appended for the vector env (``None`` for the magnitude env)."""
    action = [unwrapped.mapping.action_for(mason)]
    if direction is not None:
        from dipenv.actions import action_from_direction

        action += list(action_from_direction(DIRECTIONS[direction]))
    return action


def run_point(payload: dict[str, Any]) -> dict[str, Any]:
    """One constant field over the start states and realisations (a task); writes the point's record
    (every episode it holds, kept from earlier runs too) and returns it with the requested episodes."""
    env = make_env(payload["env_id"], payload["env_kwargs"])
    unwrapped: Any = env.unwrapped
    action = constant_action(unwrapped, payload["mason_number"], payload["direction"])
    key = library_key(unwrapped)
    settings = unwrapped.settings()
    # The physics (and the failure penalty, which a stored failed step keeps): the returns are rescored
    # below for the reward in use.
    settings["failure_penalty"] = settings.pop("reward")["failure_penalty"]
    identity = _identity(payload, key, settings)
    record = {
        "identity": identity,
        "label": payload["label"],
        "mason_number": payload["mason_number"],
        "direction": payload["direction"],
        "action": action,
        "episodes": [],
    }
    record = play_missing(
        record, payload, env, lambda: constant_policy(action), lambda old: _finite(old.get("identity"))
    )
    env.close()
    return record


def play_missing(
    record: dict[str, Any], payload: dict[str, Any], env: Any, make_policy: Any, stored_identity: Any
) -> dict[str, Any]:
    """Fill ``record`` (whose ``identity`` is set) with the episodes of ``payload`` (``split``, the first
    ``episodes`` states, ``repeats`` realisations each, default 1; with ``schedules``, the first
    ``episodes`` entries of a schedules file, :func:`agents.schedules.episodes_payload`), reusing those of
    the file ``payload['path']`` when ``stored_identity(stored record)`` equals the identity (and, for a
    schedules file, each episode's start state and schedule digest its entry's), playing the rest with
    ``make_policy()`` and writing the file after each; all episodes rescored with the env's reward. Returns
    the record with the requested episodes only (the file keeps every stored one)."""
    path = Path(payload["path"])
    reward = env.unwrapped.reward_function
    indices = range(payload["episodes"])
    repeats = int(payload.get("repeats", 1))
    scheduled = payload.get("schedules")
    stored: list[dict[str, Any]] = []
    dropped = False
    if path.exists():
        old = read_json(path)
        if stored_identity(old) == record["identity"]:
            stored = list(old["episodes"])
            if scheduled is not None:
                stored = [e for e in stored if matches(e, scheduled)]
                dropped = len(stored) < len(old["episodes"])
            if not dropped and not missing(stored, indices, repeats):
                old = rescore_stored(old, reward, path)
                return {**old, "episodes": select(old["episodes"], indices, repeats)}
    for index, realisation in missing(stored, indices, repeats):
        if scheduled is None:
            trace = run_episode(env, make_policy(), payload["split"], index, realisation=realisation)
            stored.append({**trace.summary(), "trace": trace.to_dict()})
        else:
            stored.append(play(env, make_policy(), payload["split"], scheduled[index], realisation))
        stored.sort(key=episode_key)
        record["episodes"] = stored
        write_json(path, rescore(record, reward))
        dropped = False
    record["episodes"] = stored
    if dropped:  # episodes of other schedules removed, none played: the file holds the kept ones
        write_json(path, rescore(record, reward))
    return {**record, "episodes": select(stored, indices, repeats)}


def rescore(record: dict[str, Any], reward: Any) -> dict[str, Any]:
    """``record`` with every episode's per-step rewards and return recomputed by ``reward``
    (a :class:`dipenv.rewards.ViscosityTargetReward`) from its stored ``eta_r`` and field energy.

    A constant-field point's physics does not depend on the reward, so one run serves any target or
    energy weight. The failure reward of a failed episode (its last entry) is kept as stored.
    """
    for episode in record["episodes"]:
        trace = episode["trace"]
        rewards = [
            reward(eta, energy)[0] for eta, energy in zip(trace["eta_r"], trace["field_energy"], strict=True)
        ]
        if trace["failed"]:
            rewards.append(trace["reward"][-1])
        trace["reward"] = rewards
        episode["return"] = float(np.sum(rewards))
    return record


def rescore_stored(record: dict[str, Any], reward: Any, path: Path) -> dict[str, Any]:
    """:func:`rescore` of a record stored at ``path``, written back there if its returns changed, so that
    the stored rewards are always those of the last reward used."""
    before = [e["return"] for e in record["episodes"]]
    record = rescore(record, reward)
    if [e["return"] for e in record["episodes"]] != before:
        write_json(path, record)
    return record


def _identity(payload: dict[str, Any], library_key: str | None, settings: dict[str, Any]) -> dict[str, Any]:
    """What a point's result depends on (a stored point is reused only if this matches): the command's
    arguments and the env's resolved physical settings (``FieldControlEnv.settings`` less the reward),
    so a changed default of the env is not silently reused; with a schedules file, its digest."""
    digest = payload.get("schedules_digest")
    return _finite(
        {
            "env_settings": settings,
            "env_id": payload["env_id"],
            "env_kwargs": {k: v for k, v in payload["env_kwargs"].items() if k not in RESCORED_KWARGS},
            "split": payload["split"],
            "episodes": payload["episodes"],
            "mason_number": payload["mason_number"],
            "direction": payload["direction"],
            "library_key": library_key,
            **({"schedules": digest} if digest is not None else {}),
        }
    )


def stored_points(folder: Path, records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The other points stored in ``folder`` that belong to the same study as ``records`` (identity equal
    but for the field), with every episode they hold: a command that runs a few points again (more
    ``--repeats``, say) still summarises the whole folder."""

    def study(identity: dict[str, Any]) -> dict[str, Any]:
        return {k: v for k, v in identity.items() if k not in ("mason_number", "direction")}

    reference = study(_finite(records[0]["identity"]))
    labels = {r["label"] for r in records}
    out = []
    for path in sorted(folder.glob("*.json")):
        if path.stem in labels:
            continue
        try:
            record = read_json(path)
            same = study(_finite(record["identity"])) == reference
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if same:
            out.append(record)
    return out


def summarise_points(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per point: means and 95% intervals over start states (each state's realisations averaged first),
    and the Pareto flag (eta_r, energy)."""
    rows = []
    for record in records:
        eps = record["episodes"]
        states, eta_per_state = per_state(eps, "eta_second_half")
        eta_stats = interval_estimates(eta_per_state.tolist())
        eta, eta_lo, eta_hi = eta_stats["mean"], eta_stats["ci_low"], eta_stats["ci_high"]
        energy = float(np.nanmean(per_state(eps, "energy_second_half")[1]))
        ret_stats = interval_estimates(per_state(eps, "return")[1].tolist())
        ret, ret_lo, ret_hi = ret_stats["mean"], ret_stats["ci_low"], ret_stats["ci_high"]
        rows.append(
            {
                "label": record["label"],
                "mason_number": record["mason_number"],
                "direction": record["direction"],
                "action": record["action"],
                "eta_second_half": eta,
                "eta_ci_low": eta_lo,
                "eta_ci_high": eta_hi,
                "energy": energy,
                "return": ret,
                "return_ci_low": ret_lo,
                "return_ci_high": ret_hi,
                "episodes": len(states),
                "repeats": len(eps) // max(len(states), 1),
                "failures": sum(bool(e["failed"]) for e in eps),
            }
        )
    for row in rows:
        row["pareto"] = not any(
            o["eta_second_half"] <= row["eta_second_half"]
            and o["energy"] <= row["energy"]
            and (o["eta_second_half"] < row["eta_second_half"] or o["energy"] < row["energy"])
            for o in rows
        )
    return rows


def plot_pareto(rows: list[dict[str, Any]], path: Path, policies: list[dict[str, Any]] | None = None) -> None:
    """eta_r (second half) against field energy; the front joined; policies with their intervals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.2))
    energy_floor = min([r["energy"] for r in rows if r["energy"] > 0] + [1e-2]) / 3
    x = [max(r["energy"], energy_floor) for r in rows]
    y = [r["eta_second_half"] for r in rows]
    err = [
        [r["eta_second_half"] - r["eta_ci_low"] if math.isfinite(r["eta_ci_low"]) else 0 for r in rows],
        [r["eta_ci_high"] - r["eta_second_half"] if math.isfinite(r["eta_ci_high"]) else 0 for r in rows],
    ]
    ax.errorbar(x, y, yerr=err, fmt="o", color="0.5", label="constant field", zorder=2)
    front = sorted((xi, yi) for xi, yi, r in zip(x, y, rows, strict=True) if r["pareto"])
    if front:
        ax.plot(*zip(*front, strict=True), "-", color="0.2", label="Pareto front (constant)", zorder=1)
    for xi, yi, r in zip(x, y, rows, strict=True):
        ax.annotate(r["label"], (xi, yi), fontsize=6, xytext=(3, 3), textcoords="offset points")
    for policy in policies or []:
        ax.errorbar(
            [max(policy["energy"], energy_floor)],
            [policy["eta"]],
            yerr=[[policy["eta"] - policy["eta_ci_low"]], [policy["eta_ci_high"] - policy["eta"]]],
            fmt="s",
            ms=7,
            label=policy["name"],
            zorder=3,
        )
    ax.set_xscale("log")
    ax.set_xlabel(f"field energy <eps E0^2> = <1/Mn> (eta gammadot; off plotted at {energy_floor:.2g})")
    ax.set_ylabel("eta_r, second half of the episode")
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def parse_mason(text: str) -> list[float]:
    values = []
    for part in text.split(","):
        part = part.strip()
        values.append(math.inf if part in ("off", "inf") else float(part))
    return values


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("--env", required=True, help="environment id, e.g. dipenv/FieldMagnitude-v0")
    parser.add_argument("--out", required=True, type=directory, help="output folder (created; reruns resume)")
    parser.add_argument(
        "--mason", default=None, help="comma-separated Mason numbers or 'off' (default: a grid)"
    )
    parser.add_argument(
        "--directions",
        default=None,
        help=f"vector envs only: named directions from {', '.join(DIRECTIONS)} (default: all of them)",
    )
    parser.add_argument("--split", default="test", choices=("train", "validation", "test", "fresh"))
    parser.add_argument("--episodes", type=int, default=None, help="start states (default: the whole split)")
    parser.add_argument(
        "--repeats",
        type=integer_at_least(1),
        default=1,
        help="realisations per start state (dipenv.realisations; default 1: the stored state), >= 1",
    )
    parser.add_argument(
        "--schedules",
        type=Path,
        default=None,
        metavar="FILE",
        help="thickening-control envs: a JSON list of shear-rate schedules (optionally with start_index) "
        "played instead of the split's own, episode j on schedule j from a start state of --split "
        "(agents.schedules; docs/agents.md#your-own-schedules)",
    )
    parser.add_argument("--env-kwargs", default="{}", help="JSON object of extra environment arguments")
    parser.add_argument("--workers", type=integer_at_least(1), default=1, help="local worker processes, >= 1")
    parser.add_argument(
        "--scheduler",
        type=scheduler_address,
        default=None,
        help="Dask scheduler address, tcp://HOST:PORT (instead of local workers)",
    )
    add_folder_options(parser)
    return parser


LEGACY = ("pareto.json", "best_constant.json")
"""Files of an open-loop folder written before manifests (``points/`` is no marker: the controllers
write one too)."""


def folder_identity(
    env_id: str, env_kwargs: dict[str, Any], split: str, episodes: int, schedules: str | None = None
) -> dict[str, Any]:
    """The identity in an open-loop folder's manifest (the module docstring); ``schedules``: the digest
    of a schedules file (:mod:`agents.schedules`), None for the split's own schedules."""
    kept = {k: v for k, v in env_kwargs.items() if k not in RESCORED_KWARGS and k != "progress"}
    identity = {"env_id": env_id, "env_kwargs": kept, "split": split, "episodes": episodes}
    return identity if schedules is None else {**identity, "schedules": schedules}


def legacy_problem(folder: Path, requested: dict[str, Any]) -> str | None:
    """Why a pre-manifest open-loop ``folder`` cannot be adopted for the identity ``requested``, or None:
    a stored point was made with another env, env arguments, split or number of start states (a
    controller's point, which is no constant field, too)."""
    if (folder / "manifest.json").exists():
        return None
    for path in sorted((folder / "points").glob("*.json")):
        try:
            record = read_json(path)
            identity = record["identity"]
            recorded = folder_identity(
                identity["env_id"],
                dict(identity["env_kwargs"]),
                identity["split"],
                identity["episodes"],
                identity.get("schedules"),
            )
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
            return f"--out {folder}: {path} is not an open-loop point ({type(error).__name__}: {error})"
        if "controller" in record or not isinstance(record.get("mason_number"), float | int):
            return f"--out {folder}: {path} is not a constant field's point (an agents.controllers point?)"
        problem = legacy_conflict(folder, path, recorded, requested)
        if problem is not None:
            return problem
    return None


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    args = build_parser().parse_args(argv)
    env_kwargs = json_object(PROG, "--env-kwargs", args.env_kwargs)
    output_directory(PROG, args.out)
    env = checked_env(PROG, args.env, env_kwargs, progress=True)
    unwrapped: Any = env.unwrapped
    mapping = unwrapped.mapping
    schedules: ScheduleSet | None = None
    if args.schedules is None:
        episodes = split_size(PROG, unwrapped, args.split, args.episodes)
    else:
        schedules = load_schedules(PROG, args.schedules, unwrapped, args.env, args.split)
        episodes = episode_count(PROG, schedules, args.episodes)
    if args.mason is None:
        masons = [m for m in parse_mason(",".join(str(v) for v in DEFAULT_MASON))]
        masons = [m for m in masons if math.isinf(m) or mapping.mason_min <= m <= mapping.mason_max]
        masons += [mapping.mason_min, mapping.mason_max]
        masons = sorted(set(masons), reverse=True, key=lambda m: m)
    else:
        try:
            masons = parse_mason(args.mason)
        except ValueError:
            usage_error(PROG, f"--mason takes 'off' or numbers separated by commas, got {args.mason!r}")
        twice = sorted({m for m in masons if masons.count(m) > 1})
        if twice:
            listed = ", ".join(point_label(m, None) for m in twice)
            usage_error(PROG, f"--mason lists {listed} twice in {args.mason!r} (each point once)")
    for m in masons:
        if not (math.isinf(m) or mapping.mason_min <= m <= mapping.mason_max):
            usage_error(
                PROG, f"--mason {m:g} is outside the env's range [{mapping.mason_min}, {mapping.mason_max}]"
            )
    directions: list[str | None] = [None]
    vector_field = bool(getattr(unwrapped, "vector_field", False))  # the surrogate envs: strength only
    if not vector_field and args.directions is not None:
        usage_error(
            PROG, f"--directions is for the vector-field envs; --env {args.env} sets the field strength only"
        )
    if vector_field:
        directions = [d.strip() for d in (args.directions or ",".join(DIRECTIONS)).split(",")]
        for d in directions:
            if d not in DIRECTIONS:
                usage_error(PROG, f"--directions: unknown {d!r}; choose from {', '.join(DIRECTIONS)}")
        if len(set(directions)) < len(directions):
            usage_error(PROG, f"--directions lists a direction twice: {args.directions!r}")
    identity = folder_identity(
        args.env, env_kwargs, args.split, episodes, None if schedules is None else schedules.digest
    )
    if not args.overwrite:
        problem = legacy_problem(args.out, identity)
        if problem is not None:
            usage_error(PROG, problem)
        for path in sorted((args.out / "points").glob("*.json")):  # stored points a rerun reuses
            try:
                stored = read_json(path)
            except (OSError, UnicodeDecodeError, ValueError) as exc:
                usage_error(
                    PROG,
                    f"{path} is damaged ({exc}): delete that file (its point is played again) or give "
                    "--overwrite",
                )
            if not (isinstance(stored, dict) and isinstance(stored.get("episodes"), list)):
                usage_error(PROG, f"{path} is not a point record: delete that file or give --overwrite")
    claim_out(
        PROG,
        args.out,
        "agents.open_loop",
        identity,
        argv=command_line("agents.open_loop", argv),
        resume=args.resume,
        overwrite=args.overwrite,
        legacy=legacy_markers(args.out, LEGACY, "agents.open_loop"),
    )
    write_command(args.out, "agents.open_loop", argv)
    (args.out / "points").mkdir(parents=True, exist_ok=True)
    compile_notice(args.scheduler)
    if schedules is None:
        if callable(getattr(unwrapped, "library", None)):  # the surrogate envs have none
            # once, before the workers start; only the states played
            unwrapped.library().ensure([args.split], progress=True, count=episodes)
    else:
        write_json(args.out / "schedules.json", schedules.resolved())
        prepare_states(unwrapped, schedules, episodes)
    env.close()
    scheduled = episodes_payload(schedules)
    payloads = []
    for m in masons:
        for d in directions if not math.isinf(m) else directions[:1]:
            label = point_label(m, d)
            payloads.append(
                {
                    "env_id": args.env,
                    "env_kwargs": {**env_kwargs, "progress": False},
                    "split": args.split,
                    "episodes": episodes,
                    "repeats": args.repeats,
                    "mason_number": m,
                    "direction": d,
                    "label": label,
                    "path": str(args.out / "points" / f"{label}.json"),
                    **(
                        {"schedules": scheduled[:episodes], "schedules_digest": schedules.digest}
                        if schedules is not None and scheduled is not None
                        else {}
                    ),
                }
            )
    records = run_tasks(run_point, payloads, workers=args.workers, scheduler=args.scheduler)
    records += [rescore(r, unwrapped.reward_function) for r in stored_points(args.out / "points", records)]
    rows = summarise_points(records)
    best = max(rows, key=lambda r: r["return"])
    write_json(
        args.out / "pareto.json",
        {
            "env_id": args.env,
            "env_kwargs": env_kwargs,
            "split": args.split,
            "library_key": records[0]["identity"]["library_key"],
            **({"schedules": schedules.summary()} if schedules is not None else {}),
            "points": rows,
        },
    )
    write_json(args.out / "best_constant.json", best)
    columns = [
        "label",
        "mason_number",
        "direction",
        "eta_second_half",
        "eta_ci_low",
        "eta_ci_high",
        "energy",
        "return",
        "return_ci_low",
        "return_ci_high",
        "episodes",
        "failures",
        "pareto",
    ]
    lines = [",".join(columns)] + [",".join(str(r[c]) for c in columns) for r in rows]
    write_text_atomic(args.out / "pareto.csv", "\n".join(lines) + "\n")
    plot_pareto(rows, args.out / "pareto.png")
    played = (
        f"{episodes} {args.split} states"
        if schedules is None
        else (
            schedules.label()
            if episodes == len(schedules)
            else f"the first {episodes} of {schedules.label()}"
        )
        + f", start states of {args.split}"
    )
    print(
        f"| point | eta_r (2nd half) | 95% CI | energy <1/Mn> | return | Pareto |  "
        f"({played} x {args.repeats} realisations)"
    )
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['label']} | {r['eta_second_half']:.3f} | [{r['eta_ci_low']:.3f}, {r['eta_ci_high']:.3f}] "
            f"| {r['energy']:.3f} | {r['return']:.2f} | {'yes' if r['pareto'] else ''} |"
        )
    print(f"best constant for the reward: {best['label']} (return {best['return']:.2f})")
    return rows


if __name__ == "__main__":
    main()
