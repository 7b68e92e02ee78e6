"""Does a policy beat constant fields? Its position against the constant-field front, and its variation.

The open-loop points are ``(E_k, eta_k)``: field energy ``E = <1/Mn>`` (``eta gammadot`` per unit strain
in simulation units; 0 with the field off) and the time-averaged ``eta_r`` over the second half of the
episode. Their Pareto front (no point has both lower ``eta_r`` and lower energy), sorted by energy, is
joined by straight lines and held flat beyond its last point (a stronger field is never required to be
used). For a policy at ``(E_p, eta_p)``:

* ``front_eta``: the front's ``eta_r`` at ``E_p``; ``eta_p`` below it is "lower eta_r at equal energy".
* ``front_energy``: the least energy at which the front reaches ``eta_p`` (``inf`` if it never does);
  ``E_p`` below it is "equal eta_r at lower energy".

Joining adjacent front points linearly is what switching between the two constant fields for a fraction of
the time would give if the suspension followed each field at once (it does not: the relaxation strains are
0.5-2), so the straight segments are a demanding baseline between the measured points, not a measurement.

The verdict uses the policy's 95% bootstrap interval over training seeds (:mod:`agents.statistics`):
"below the front" if its upper end is below ``front_eta``, "above" if its lower end is above, otherwise
"on the front". The action variation
(second half of each episode) tells whether a policy is more than a constant: the standard deviation of its
action (in the action box, [-1, 1]), the share of intervals with the field off, and the 10th-90th
percentile range of the Mason numbers it used.

The verdict above counts the policy's noise and not the front's: the constant points are episode averages
over the same start states and carry a noise of their own (about ±0.3 in ``eta_r`` at 16 states).
``paired_front_gap`` counts both and drops what they share: per start state ``s`` the front is rebuilt from
the front points' own ``eta_r`` on that state (the same Pareto members, at their energies), and the policy's
``eta_r`` on that state (averaged over seeds and realisations) is compared with it at the policy's mean
energy. The mean gap over the states and its 95% bootstrap interval over them give the paired verdict:
"below the front, paired per state" if the interval lies below 0. The mean gap equals ``eta_minus_front``
when the front points are the state averages (the interpolation is linear in the ``eta_r`` values). The
energy is the policy's mean, not its energy on each state: a constant field is one choice for every state,
and per-state energies would credit the policy with the front's convexity (a mixture of constants that
no single constant can give). Between front points it inherits the straight-segment caveat above.

The return (the reward the policy was trained for) is compared with the best constant field's on the
same start states: per training seed, the policy's mean return minus the constant's mean return over
those states (a paired comparison: the states' spread, common to both, drops out), then the mean and its
95% bootstrap interval over seeds (:mod:`agents.statistics`, rliable). "higher return" if the interval's
lower end is above 0, "lower" if its upper end is below, otherwise "same return within the 95% interval".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from agents.statistics import interval_estimates


def front_points(rows: Sequence[dict[str, Any]]) -> list[tuple[float, float]]:
    """The Pareto points ``(energy, eta_r)`` of :func:`agents.open_loop.summarise_points` rows, by energy."""
    points = sorted((float(r["energy"]), float(r["eta_second_half"])) for r in rows if r["pareto"])
    if not points:
        raise ValueError("rows: no Pareto point (every row has pareto=False)")
    return points


def front_eta(front: Sequence[tuple[float, float]], energy: float) -> float:
    """The front's ``eta_r`` at ``energy`` (linear between points, flat beyond the ends)."""
    if not math.isfinite(energy) or energy < 0:
        raise ValueError(f"energy must be finite and >= 0, got {energy}")
    e = np.array([p[0] for p in front])
    eta = np.array([p[1] for p in front])
    return float(np.interp(energy, e, eta))


def front_energy(front: Sequence[tuple[float, float]], eta: float) -> float:
    """The least energy at which the front reaches ``eta`` (``inf`` below its lowest ``eta_r``)."""
    if not math.isfinite(eta):
        raise ValueError(f"eta must be finite, got {eta}")
    if eta >= front[0][1]:
        return front[0][0]
    for (e0, y0), (e1, y1) in zip(front[:-1], front[1:], strict=True):
        if y1 <= eta:
            return e0 + (e1 - e0) * (y0 - eta) / (y0 - y1)
    return math.inf


def side(value: float, low: float, high: float, reference: float) -> int:
    """-1 if the interval ``[low, high]`` lies below ``reference``, +1 if above, 0 if it holds it (a NaN
    interval, from one sample, stands for the point ``value``)."""
    low = value if math.isnan(low) else low
    high = value if math.isnan(high) else high
    return -1 if high < reference else 1 if low > reference else 0


def position(
    front: Sequence[tuple[float, float]], energy: float, eta: float, eta_low: float, eta_high: float
) -> dict[str, Any]:
    """Where a policy sits against the front (see the module docstring); intervals may be NaN."""
    reference = front_eta(front, energy)
    verdict = {
        -1: "below the constant-field front (lower eta_r at equal energy)",
        1: "above the constant-field front (a constant field does better)",
        0: "on the constant-field front (within the 95% interval)",
    }[side(eta, eta_low, eta_high, reference)]
    if math.isnan(eta_low) or math.isnan(eta_high):
        verdict += "; one sample, no interval"
    return {
        "front_eta": reference,
        "eta_minus_front": eta - reference,
        "front_energy": front_energy(front, eta),
        "verdict": verdict,
    }


def _gap_verdict(gaps: list[float], words: dict[int, str], single: str) -> tuple[float, float, float, str]:
    """Mean of ``gaps`` with its 95% bootstrap interval, and ``words[side]`` of the interval against 0
    (``single`` appended where one gap gives no interval)."""
    stats = interval_estimates(gaps)
    mean, low, high = stats["mean"], stats["ci_low"], stats["ci_high"]
    verdict = words[side(mean, low, high, 0.0)] if gaps else ""
    if gaps and math.isnan(low):
        verdict += single
    return mean, low, high, verdict


def paired_front_gap(
    front_energies: Sequence[float],
    front_states: Sequence[Sequence[float]],
    eta_states: Sequence[float],
    energy: float,
) -> dict[str, Any]:
    """``eta_r`` minus the front, paired per start state (see the module docstring).

    ``front_energies`` (``m``, increasing) are the front points' energies, ``front_states`` their
    ``(m, n)`` per-state ``eta_r``; ``eta_states`` (``n``) the policy's per-state ``eta_r`` and
    ``energy`` its mean energy. NaN (and verdict "not paired") where the shapes differ or a value is not
    finite (a state missing from a point, a failed episode)."""
    energies = np.asarray(front_energies, dtype=float)
    front = np.asarray(front_states, dtype=float)
    eta = np.asarray(eta_states, dtype=float)
    if energies.ndim != 1 or np.any(np.diff(energies) <= 0):
        raise ValueError(f"front_energies must increase strictly, got {energies.tolist()}")
    pairable = (
        front.shape == (energies.size, eta.size)
        and eta.size > 0
        and math.isfinite(energy)
        and np.isfinite(front).all()
        and np.isfinite(eta).all()
    )
    if not pairable:
        nan = math.nan
        keys = ("front_gap", "front_gap_low", "front_gap_high")
        return {
            **dict.fromkeys(keys, nan),
            "states_below_front": 0,
            "front_states": 0,
            "paired_verdict": "not paired",
        }
    reference = np.array([np.interp(energy, energies, front[:, s]) for s in range(eta.size)])
    gaps = eta - reference
    words = {
        -1: "below the front, paired per state",
        1: "above the front, paired per state",
        0: "on the front, paired per state (within the 95% interval)",
    }
    mean, low, high, verdict = _gap_verdict(gaps.tolist(), words, "; one state, no interval")
    return {
        "front_gap": mean,
        "front_gap_low": low,
        "front_gap_high": high,
        "states_below_front": int(np.sum(gaps < 0)),
        "front_states": int(gaps.size),
        "paired_verdict": verdict,
    }


def action_variation(episodes: Sequence[dict[str, Any]]) -> dict[str, float]:
    """Second-half action statistics over episodes with a ``trace`` (see the module docstring)."""
    stds, off, used = [], [], []
    for episode in episodes:
        trace = episode["trace"]
        n = len(trace["action"])
        if n == 0:
            continue
        half = slice(n // 2, n)
        actions = np.asarray(trace["action"], dtype=float)[half]
        stds.append(float(actions.std(axis=0).mean()))
        mason = np.array([float(m) for m in trace["mason_number"]])[half]
        off.append(float(np.mean(~np.isfinite(mason))))
        used.extend(mason[np.isfinite(mason)].tolist())
    if not stds:
        return {"action_std": math.nan, "off_share": math.nan, "mason_p10": math.nan, "mason_p90": math.nan}
    p10, p90 = (float(v) for v in np.percentile(used, [10, 90])) if used else (math.nan, math.nan)
    return {
        "action_std": float(np.mean(stds)),
        "off_share": float(np.mean(off)),
        "mason_p10": p10,
        "mason_p90": p90,
    }


def return_gap(per_seed_returns: Sequence[float], reference: float) -> dict[str, Any]:
    """Policy return minus a reference return on the same states, over seeds (module docstring)."""
    if not math.isfinite(reference):
        raise ValueError(f"reference must be a finite return, got {reference}")
    gaps = [r - reference for r in per_seed_returns if math.isfinite(r)]
    words = {1: "higher return", -1: "lower return", 0: "same return within the 95% interval"}
    mean, low, high, verdict = _gap_verdict(gaps, words, "; one sample, no interval")
    if not gaps:
        verdict = "no finite return"
    return {
        "return_gap": mean,
        "return_gap_low": low,
        "return_gap_high": high,
        "seeds_above": sum(g > 0 for g in gaps),
        "return_verdict": verdict,
    }


ENERGY_SAVING_TARGET = 0.30
"""Issue 21's target: at least 30% less field energy than the best constant field, at equal or lower
thickening penalty."""


def energy_target(
    energy_states: Sequence[float],
    excess_states: Sequence[float],
    best_energy_states: Sequence[float],
    best_excess_states: Sequence[float],
    target: float = ENERGY_SAVING_TARGET,
    resamples: int = 10_000,
) -> dict[str, Any]:
    """Field energy saved against the best constant field, and the thickening penalty's change, paired per
    start state (issue 21's target for the thickening-control study).

    Inputs are per start state (a policy's seeds and every row's realisations averaged first): the
    whole-episode field energy ``<eps E0^2>`` and the excess ``eta_r`` over the cap, of the row and of the
    best constant field, on the same states in the same order.

    * ``energy_saved = 1 - sum_s E_s / sum_s E_best,s`` (the saving of the mean energy), with a 95%
      percentile bootstrap interval that resamples the states (paired: the same states for both; numpy's
      generator seeded with 0, ``resamples`` draws).
    * ``excess_gap``: the mean over states of ``X_s - X_best,s`` with its 95% bootstrap interval
      (:mod:`agents.statistics`); ``states_less_excess`` counts the states where the row thickens less.
    * ``target_verdict``: "met" if the interval of the saving lies at or above ``target`` and the row does
      not thicken more (the excess gap's interval is not above 0); "not met" if the saving's interval lies
      below ``target`` or the row thickens more; else "not resolved" (the saving's interval spans the
      target). The parts are spelled out in ``energy_verdict`` and ``excess_verdict``.

    NaN and "not paired" where the lengths differ, a value is not finite or the constant spends no energy.
    """
    e, x = np.asarray(energy_states, dtype=float), np.asarray(excess_states, dtype=float)
    e0, x0 = np.asarray(best_energy_states, dtype=float), np.asarray(best_excess_states, dtype=float)
    arrays = (e, x, e0, x0)
    if (
        len({a.shape for a in arrays}) != 1
        or e.ndim != 1
        or e.size == 0
        or not all(np.isfinite(a).all() for a in arrays)
        or e0.sum() <= 0
    ):
        nan = math.nan
        keys = ("energy_saved", "energy_saved_low", "energy_saved_high", "excess_gap", "excess_gap_low")
        return {
            **dict.fromkeys((*keys, "excess_gap_high"), nan),
            "states_less_excess": 0,
            "target_states": 0,
            "energy_verdict": "not paired",
            "excess_verdict": "not paired",
            "target_verdict": "not paired",
        }
    saved = 1.0 - e.sum() / e0.sum()
    if e.size > 1:
        rng = np.random.default_rng(0)
        draws = rng.integers(0, e.size, size=(resamples, e.size))
        totals = e0[draws].sum(axis=1)
        valid = totals > 0
        boot = 1.0 - e[draws].sum(axis=1)[valid] / totals[valid]
        low, high = (float(v) for v in np.percentile(boot, [2.5, 97.5]))
    else:
        low = high = math.nan
    gaps = (x - x0).tolist()
    words = {-1: "thickens less", 1: "thickens more", 0: "same thickening within the 95% interval"}
    gap, gap_low, gap_high, excess_verdict = _gap_verdict(gaps, words, "; one state, no interval")
    percent = f"{100 * target:.0f}%"
    if math.isnan(low):
        energy_verdict = f"saves {100 * saved:.0f}%; one state, no interval"
        resolved = None
    elif low >= target:
        energy_verdict, resolved = f"saves at least {percent}", True
    elif high < target:
        energy_verdict, resolved = f"saves less than {percent}", False
    else:
        energy_verdict, resolved = f"the saving's interval spans {percent}", None
    more = side(gap, gap_low, gap_high, 0.0) == 1
    if resolved is False or more:
        target_verdict = "not met"
    elif resolved:
        target_verdict = "met"
    else:
        target_verdict = "not resolved"
    return {
        "energy_saved": float(saved),
        "energy_saved_low": low,
        "energy_saved_high": high,
        "excess_gap": gap,
        "excess_gap_low": gap_low,
        "excess_gap_high": gap_high,
        "states_less_excess": int(np.sum(x < x0)),
        "target_states": int(e.size),
        "energy_verdict": energy_verdict,
        "excess_verdict": excess_verdict,
        "target_verdict": target_verdict,
    }
