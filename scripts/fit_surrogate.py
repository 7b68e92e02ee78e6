"""Fit a surrogate (issues 43, 44) on simulator episodes, compare the routes, keep the best.

    python scripts/fit_surrogate.py DATA_DIR --out FILE.npz [--seeds 0-49] [--routes lambda,ensemble]
        [--cross-validate] [--keep auto] [--seed 0] [--holdout-mod 5] [--samples 32] [--members 5]
        [--hidden 64] [--max-epochs 400]

``DATA_DIR`` is a folder of ``scripts/surrogate_data.py`` (``episodes/ep<seed>.npz`` and its
``manifest.json``, whose env id gives the interval, the schedule's pieces, the cap and the weight). The
episodes are split **by seed**: seed ``s`` is held out when ``s % holdout_mod == holdout_mod - 1`` (every
fifth seed by default; the behaviours cycle with period 4, so every behaviour is held out), the rest fit.
The split does not move when more episodes arrive; ``--seeds`` fixes the episodes used (the data folder of
a running generator grows), so that the command recorded with the model repeats the fit.

Routes (``docs/surrogate.md``; inference in :mod:`dipenv.surrogate.models`):

* ``lambda``: the structural-kinetics model. Its 9 nonlinear parameters (scipy ``least_squares``, several
  starts drawn with ``--seed``) minimise the squared errors of all 12 outputs, each scaled by its sd
  (``eta_r`` weighted x2), the 11 x 12 linear read-out solved for each guess (variable projection). Then
  the noise: per output an AR(1) coefficient ``exp(-(a + b strain))`` on the residuals, a variance linear
  in ``(1, mean lambda_F, mean lambda_T)`` on the innovations, and the innovations' correlation.
* ``ensemble``: ``--members`` MLPs (2 hidden layers of ``--hidden`` SiLU units) trained with torch (one
  thread) on the Gaussian negative log-likelihood of the change of the frame's dynamic part, each on a
  bootstrap of the fitting intervals (PETS), with soft-bounded log-variances; early stopping on a tenth
  of the fitting episodes (by seed).

**Tracking data** (a data folder of ``dipenv/ViscosityTracking*``, whose episodes hold each interval's field
direction): the ensemble is fitted with the direction block of :mod:`dipenv.surrogate.features` (the
traceless ``e e^T - I/3`` of this and the previous interval's direction and this interval's field
stress scale, 15 more inputs; the model's
metadata say ``direction_inputs: true``), and the returns below are the tracking reward's,
``-(|eta_r - target| + w_E / Mn_ref)`` with each interval's recorded target. The lambda model knows fields
along ``y`` only and is refused there; ``--routes`` defaults to ``ensemble``. A folder that mixes episodes
with and without directions is refused.

Both are scored on the held-out episodes: one-step error of the interval ``eta_r`` (the model's mean
given the observed frame before it; persistence as a reference), open-loop rollouts (``--samples`` per
episode under the recorded fields and schedule, from the recorded first frame): error of the rollouts'
mean, their spread against that error, the 90% band's coverage, and the episode returns (Spearman rank
correlation with the data's, and the behaviours' order). ``--cross-validate`` also fits every route on
the other folds (held out: ``s % holdout_mod == r`` for each ``r``) and scores it on the pooled held-out
episodes, every episode once, with a paired bootstrap of the routes' difference; the saved models are
still those of the first split. ``--keep auto`` keeps the route with the lower rollout error of ``eta_r``
(the reward's input; cross-validated when run), unless its spread is off by more than a factor 1.5 and the
other's is not. Written: ``FILE.npz`` (the kept model, with the provenance and metrics in its metadata)
and ``FILE.metrics.json`` (every route's metrics, the choice and why).
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import optimize, stats

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import sim  # noqa: E402
from dipenv.surrogate.data import Episode, data_settings, load_episodes  # noqa: E402
from dipenv.surrogate.features import (  # noqa: E402
    N_DYNAMIC,
    Y_AXIS,
    inverse_signed_log,
    mlp_inputs,
)
from dipenv.surrogate.models import (  # noqa: E402
    LAMBDA_PARAMETERS,
    N_LAMBDA_FEATURES,
    EnsembleModel,
    LambdaModel,
    SurrogateModel,
    initial_lambda_features,
    lambda_trajectories,
    to_output_space,
)

ROUTES = ("lambda", "ensemble")
ETA_WEIGHT = 2.0
"""Weight of ``eta_r`` (the reward's input) among the lambda model's scaled outputs."""
CLIP_MARGIN = 0.1
"""Outputs are clipped to the data's range widened by this fraction of it on each side."""


# -- data ------------------------------------------------------------------------------------------------
def split_episodes(episodes: list[Episode], mod: int) -> tuple[list[Episode], list[Episode]]:
    """(fit, held out): seed ``s`` is held out when ``s % mod == mod - 1``."""
    held = [e for e in episodes if e.seed % mod == mod - 1]
    fit = [e for e in episodes if e.seed % mod != mod - 1]
    return fit, held


def has_directions(episodes: list[Episode]) -> bool:
    """Whether the episodes hold their fields' directions (tracking data); ``ValueError`` for a mixture."""
    held = {e.direction is not None for e in episodes}
    if len(held) > 1:
        raise ValueError("some episodes hold their fields' directions and some do not: one task per folder")
    return held == {True}


def stacked(episodes: list[Episode]) -> dict[str, Any]:
    out = {
        "dynamic": np.stack([e.dynamic for e in episodes]),
        "masons": np.stack([e.mason for e in episodes]),
        "tables": [e.table for e in episodes],
        "eta": np.stack([e.eta_r for e in episodes]),
        "energy": np.stack([e.field_energy for e in episodes]),
    }
    if has_directions(episodes):
        out["directions"] = np.stack([np.asarray(e.direction) for e in episodes])
    if all(e.target_eta_r is not None for e in episodes):
        out["targets"] = np.stack([np.asarray(e.target_eta_r) for e in episodes])
    return out


def common_arrays(episodes: list[Episode], fit: list[Episode]) -> dict[str, np.ndarray]:
    """Start frames (one per train start state, from every episode's first frame) and the output clip
    (the fitting episodes' range, widened by :data:`CLIP_MARGIN`)."""
    frames: dict[int, np.ndarray] = {}
    for e in episodes:
        frames.setdefault(e.start_index, e.dynamic[0])
    indices = sorted(frames)
    values = np.concatenate([e.dynamic for e in fit])
    low, high = values.min(axis=0), values.max(axis=0)
    span = np.maximum(high - low, 1e-6)
    return {
        "start_frames": np.stack([frames[i] for i in indices]),
        "start_indices": np.array(indices, dtype=np.int64),
        "low": low - CLIP_MARGIN * span,
        "high": high + CLIP_MARGIN * span,
    }


# -- lambda route --------------------------------------------------------------------------------------
def theta_from(u: np.ndarray) -> np.ndarray:
    """Natural parameters from the unconstrained ones (logs of the positive parameters)."""
    return np.array([u[0], math.exp(u[1]), u[2], math.exp(u[3]), *np.exp(u[4:8]), math.exp(u[8])])


def u_from(theta: np.ndarray) -> np.ndarray:
    return np.array(
        [theta[0], math.log(theta[1]), theta[2], math.log(theta[3]), *np.log(theta[4:8]), math.log(theta[8])]
    )


LAMBDA_START = np.array([0.0, 2.0, 0.3, 2.0, 0.5, 2.0, 0.5, 1.5, 0.3])
"""Default start of the lambda fit: ``Mn_F = 1``, ``Mn_T = 2``, steepness 2, build/loss strains 0.5/2
(field structure) and 0.5/1.5 (thickened structure), ``q = 0.3``."""
LAMBDA_BOUNDS = (
    np.array([-2.0, math.log(0.2), -2.0, math.log(0.2), *[math.log(0.02)] * 4, math.log(0.01)]),
    np.array([2.0, math.log(20.0), 2.0, math.log(20.0), *[math.log(50.0)] * 4, math.log(3.0)]),
)


def readout(phi: np.ndarray, y: np.ndarray, ridge: float = 1e-6) -> np.ndarray:
    """Least-squares read-out (F, D) of ``y`` (n, D) on ``phi`` (n, F), lightly ridged."""
    a = phi.T @ phi + ridge * np.eye(phi.shape[1])
    return np.linalg.solve(a, phi.T @ y)


def fit_lambda(fit: list[Episode], seed: int, starts: int) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    data = stacked(fit)
    masons, tables = data["masons"], data["tables"]
    y = to_output_space(data["dynamic"][:, 1:])
    y[..., 0] = data["eta"]
    scale = y.reshape(-1, N_DYNAMIC).std(axis=0) + 1e-9
    weights = np.ones(N_DYNAMIC)
    weights[0] = ETA_WEIGHT
    flat_y = y.reshape(-1, N_DYNAMIC)

    def residuals(u: np.ndarray) -> np.ndarray:
        phi, _ = lambda_trajectories(theta_from(u), masons, tables)
        flat = phi.reshape(-1, N_LAMBDA_FEATURES)
        b = readout(flat, flat_y)
        return (((flat_y - flat @ b) / scale) * weights).ravel()

    rng = np.random.default_rng(seed)
    low, high = LAMBDA_BOUNDS
    guesses = [u_from(LAMBDA_START)]
    guesses += [rng.uniform(low + 0.1 * (high - low), high - 0.1 * (high - low)) for _ in range(starts - 1)]
    best: Any = None
    tried = []
    for guess in guesses:
        result = optimize.least_squares(residuals, guess, bounds=(low, high), x_scale=1.0, max_nfev=300)
        tried.append(float(result.cost))
        if best is None or result.cost < best.cost:
            best = result
    theta = theta_from(best.x)
    phi, strains = lambda_trajectories(theta, masons, tables)
    b = readout(phi.reshape(-1, N_LAMBDA_FEATURES), flat_y)
    resid = y - phi @ b  # (E, T, 12)
    first = to_output_space(data["dynamic"][:, 0]) - initial_lambda_features(len(fit)) @ b
    previous = np.concatenate([first[:, None], resid[:, :-1]], axis=1)
    rho_a, rho_b = np.zeros(N_DYNAMIC), np.zeros(N_DYNAMIC)
    for j in range(N_DYNAMIC):
        r, p = resid[..., j].ravel(), previous[..., j].ravel()
        s = strains.ravel()

        def ar(ab: np.ndarray, r: np.ndarray = r, p: np.ndarray = p, s: np.ndarray = s) -> np.ndarray:
            return r - np.exp(-(ab[0] + ab[1] * s)) * p

        sol = optimize.least_squares(ar, np.array([0.5, 0.1]), bounds=([0.0, 0.0], [20.0, 20.0]))
        rho_a[j], rho_b[j] = sol.x
    rho = np.exp(-(rho_a + rho_b * strains[..., None]))
    innovations = (resid - rho * previous).reshape(-1, N_DYNAMIC)
    basis = phi.reshape(-1, N_LAMBDA_FEATURES)[:, :3]
    var_coef = np.linalg.lstsq(basis, innovations**2, rcond=None)[0]
    var_floor = 0.05 * np.mean(innovations**2, axis=0)
    sigma = np.sqrt(np.maximum(basis @ var_coef, var_floor))
    corr = np.corrcoef((innovations / sigma).T)
    chol = np.linalg.cholesky(corr + 1e-6 * np.eye(N_DYNAMIC))
    arrays = {
        "theta": theta,
        "readout": b,
        "rho_a": rho_a,
        "rho_b": rho_b,
        "var_coef": var_coef,
        "var_floor": var_floor,
        "chol": chol,
    }
    info = {
        "parameters": dict(zip(LAMBDA_PARAMETERS, (float(v) for v in theta), strict=True)),
        "starts": starts,
        "costs": tried,
        "fit_rmse_eta": float(np.sqrt(np.mean(resid[..., 0] ** 2))),
        "rho_eta_at_strain": {
            f"{g:g}": float(math.exp(-(rho_a[0] + rho_b[0] * g))) for g in (0.05, 0.25, 0.5, 1.0, 1.25)
        },
        "innovation_sd_eta": float(np.sqrt(np.mean(innovations[:, 0] ** 2))),
    }
    return arrays, info


# -- ensemble route ---------------------------------------------------------------------------------------
def transitions(episodes: list[Episode], direction: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(inputs (n, I), targets (n, 12)): every interval's inputs and the change of the dynamic part; with
    ``direction``, the inputs carry the direction block of this and the previous interval (the first
    interval's previous direction is ``y``, where the envs' reset puts the field)."""
    xs, ys = [], []
    for e in episodes:
        previous = np.concatenate([[np.inf], e.mason[:-1]])
        t = e.table
        if direction:
            if e.direction is None:
                raise ValueError(f"episode {e.seed} holds no field directions")
            now = np.asarray(e.direction, dtype=np.float64)
            before = np.concatenate([np.array([Y_AXIS]), now[:-1]])
            x = mlp_inputs(
                e.dynamic[:-1], previous, e.mason, t.rate_start, t.rate_mean, t.rate_end, before, now, True
            )
        else:
            x = mlp_inputs(e.dynamic[:-1], previous, e.mason, t.rate_start, t.rate_mean, t.rate_end)
        xs.append(x)
        ys.append(e.dynamic[1:] - e.dynamic[:-1])
    return np.concatenate(xs), np.concatenate(ys)


def fit_ensemble(
    fit: list[Episode],
    seed: int,
    members: int,
    hidden: int,
    max_epochs: int,
    patience: int,
    direction: bool = False,
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Train the ensemble (module docstring); ``direction``: with the direction block in its inputs."""
    import torch

    torch.set_num_threads(1)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    seeds = sorted(e.seed for e in fit)
    val_seeds = set(rng.choice(seeds, size=max(1, len(seeds) // 10), replace=False).tolist())
    train_eps = [e for e in fit if e.seed not in val_seeds]
    val_eps = [e for e in fit if e.seed in val_seeds]
    x_tr, y_tr = transitions(train_eps, direction)
    x_va, y_va = transitions(val_eps, direction)
    x_mean, x_std = x_tr.mean(axis=0), x_tr.std(axis=0) + 1e-6
    y_mean, y_std = y_tr.mean(axis=0), y_tr.std(axis=0) + 1e-9

    def scaled(x: np.ndarray, y: np.ndarray) -> tuple[Any, Any]:
        return (
            torch.tensor((x - x_mean) / x_std, dtype=torch.float32),
            torch.tensor((y - y_mean) / y_std, dtype=torch.float32),
        )

    xt, yt = scaled(x_tr, y_tr)
    xv, yv = scaled(x_va, y_va)
    n, d = len(xt), N_DYNAMIC
    sizes = [(x_tr.shape[1], hidden), (hidden, hidden), (hidden, 2 * d)]
    weights = []
    for fan_in, fan_out in sizes:
        w = torch.empty(members, fan_in, fan_out)
        for m in range(members):
            torch.nn.init.xavier_uniform_(w[m])
        weights += [torch.nn.Parameter(w), torch.nn.Parameter(torch.zeros(members, 1, fan_out))]
    max_lv = torch.nn.Parameter(torch.full((d,), 0.5))
    min_lv = torch.nn.Parameter(torch.full((d,), -6.0))
    params = [*weights, max_lv, min_lv]
    optimiser = torch.optim.Adam(params, lr=1e-3, weight_decay=1e-5)

    def forward(x: Any) -> tuple[Any, Any]:  # x: (M, B, I)
        h = x
        for layer in range(2):
            h = torch.nn.functional.silu(torch.bmm(h, weights[2 * layer]) + weights[2 * layer + 1])
        out = torch.bmm(h, weights[4]) + weights[5]
        mean, logvar = out[..., :d], out[..., d:]
        logvar = max_lv - torch.nn.functional.softplus(max_lv - logvar)
        logvar = min_lv + torch.nn.functional.softplus(logvar - min_lv)
        return mean, logvar

    boot = torch.tensor(rng.integers(n, size=(members, n)))
    batch = min(256, n)
    best_loss, best_state, stale, epochs = math.inf, [p.detach().clone() for p in params], 0, 0
    for _epoch in range(max_epochs):
        epochs += 1
        order = boot[:, torch.randperm(n)]
        for start in range(0, n, batch):
            idx = order[:, start : start + batch]
            mean, logvar = forward(xt[idx])
            target = yt[idx]
            nll = (((mean - target) ** 2) * torch.exp(-logvar) + logvar).mean()
            loss = nll + 0.01 * (max_lv.sum() - min_lv.sum()) / (n / batch)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
        with torch.no_grad():
            mean, logvar = forward(xv.expand(members, -1, -1))
            val = float((((mean - yv) ** 2) * torch.exp(-logvar) + logvar).mean())
        if val < best_loss - 1e-4:
            best_loss, best_state, stale = val, [p.detach().clone() for p in params], 0
        else:
            stale += 1
            if stale >= patience:
                break
    w1, b1, w2, b2, w3, b3, mx, mn = (p.numpy().astype(np.float64) for p in best_state)
    arrays = {
        "w1": w1,
        "b1": b1[:, 0],
        "w2": w2,
        "b2": b2[:, 0],
        "w3": w3,
        "b3": b3[:, 0],
        "max_logvar": mx,
        "min_logvar": mn,
        "x_mean": x_mean,
        "x_std": x_std,
        "y_mean": y_mean,
        "y_std": y_std,
    }
    info = {
        "members": members,
        "hidden": hidden,
        "epochs": epochs,
        "validation_nll": best_loss,
        "train_intervals": n,
        "validation_episodes": sorted(int(s) for s in val_seeds),
    }
    if direction:
        info["direction_inputs"] = True
    return arrays, info


# -- evaluation -------------------------------------------------------------------------------------------
def returns(eta: np.ndarray, energy: np.ndarray, cap: float, weight: float) -> np.ndarray:
    """Episode returns of the thickening penalty (last axis: intervals)."""
    return -(np.maximum(0.0, eta - cap) + weight * energy).sum(axis=-1)


def tracking_returns(eta: np.ndarray, energy: np.ndarray, target: np.ndarray, weight: float) -> np.ndarray:
    """Episode returns of the tracking reward ``-(|eta_r - target| + w_E energy)`` (last axis: intervals;
    ``target``: each interval's mean target, as the env charged it)."""
    return -(np.abs(eta - target) + weight * energy).sum(axis=-1)


def predict(
    model: SurrogateModel, held: list[Episode], settings: dict[str, Any], samples: int, seed: int
) -> dict[str, Any]:
    """Per-episode predictions on ``held`` (one-step, ``samples`` open-loop rollouts, returns)."""
    data = stacked(held)
    dynamic, masons, tables, eta = data["dynamic"], data["masons"], data["tables"], data["eta"]
    weight = settings["energy_weight"]
    rng = np.random.default_rng(seed)
    if "directions" in data:  # a model without the block ignores them
        directions = data["directions"]
        roll = model.rollout(dynamic[:, 0], masons, tables, rng, samples, directions=directions)
        one_step = model.one_step(dynamic, masons, tables, directions=directions)
    else:  # as before the direction block, call for call
        roll = model.rollout(dynamic[:, 0], masons, tables, rng, samples)
        one_step = model.one_step(dynamic, masons, tables)
    roll = inverse_signed_log(roll[..., 0])  # (E, S, T)
    if settings.get("task") == "tracking":
        target = data["targets"]
        sim_returns = tracking_returns(eta, data["energy"], target, weight)
        sur_returns = tracking_returns(roll, data["energy"][:, None, :], target[:, None, :], weight)
    else:
        cap = settings["eta_cap"]
        sim_returns = returns(eta, data["energy"], cap, weight)
        sur_returns = returns(roll, data["energy"][:, None, :], cap, weight)  # (E, S)
    return {
        "eta": eta,
        "one_step": inverse_signed_log(one_step[..., 0]),
        "persistence": inverse_signed_log(dynamic[:, :-1, 0]),
        "rollouts": roll,
        "sim_returns": sim_returns,
        "sur_returns": sur_returns,
        "behaviours": [e.behaviour for e in held],
        "seeds": [e.seed for e in held],
    }


def pooled(parts: list[dict[str, Any]]) -> dict[str, Any]:
    """The predictions of several folds as one set of episodes."""
    out: dict[str, Any] = {}
    for key in parts[0]:
        values = [p[key] for p in parts]
        out[key] = sum(values, []) if isinstance(values[0], list) else np.concatenate(values)
    return out


def metrics_of(p: dict[str, Any]) -> dict[str, Any]:
    """The held-out metrics of the module docstring from :func:`predict`'s (or :func:`pooled`'s) output."""
    eta, roll = p["eta"], p["rollouts"]
    mean = roll.mean(axis=1)
    sd = roll.std(axis=1, ddof=1)
    lo, hi = np.quantile(roll, [0.05, 0.95], axis=1)
    error = mean - eta
    sim_returns, sur_returns = p["sim_returns"], p["sur_returns"]
    behaviours = sorted(set(p["behaviours"]))
    by_behaviour = {}
    for b in behaviours:
        mask = np.array([x == b for x in p["behaviours"]])
        by_behaviour[b] = {
            "episodes": int(mask.sum()),
            "simulator": float(sim_returns[mask].mean()),
            "surrogate": float(sur_returns[mask].mean()),
        }
    order_sim = sorted(behaviours, key=lambda b: by_behaviour[b]["simulator"])
    order_sur = sorted(behaviours, key=lambda b: by_behaviour[b]["surrogate"])
    second = slice(eta.shape[1] // 2, None)
    kendall = math.nan
    if len(behaviours) > 1:
        kendall = float(
            stats.kendalltau(
                [by_behaviour[b]["simulator"] for b in behaviours],
                [by_behaviour[b]["surrogate"] for b in behaviours],
            ).statistic
        )
    return {
        "episodes": int(eta.shape[0]),
        "one_step_rmse_eta": float(np.sqrt(np.mean((p["one_step"] - eta) ** 2))),
        "persistence_rmse_eta": float(np.sqrt(np.mean((p["persistence"] - eta) ** 2))),
        "rollout_rmse_eta": float(np.sqrt(np.mean(error**2))),
        "rollout_bias_eta": float(np.mean(error)),
        "rollout_rmse_eta_second_half": float(np.sqrt(np.mean(error[:, second] ** 2))),
        "rollout_sd_eta": float(np.sqrt(np.mean(sd**2))),
        "spread_ratio": float(np.sqrt(np.mean(sd**2)) / np.sqrt(np.mean(error**2))),
        "coverage_90": float(np.mean((eta >= lo) & (eta <= hi))),
        "data_sd_eta_within_episode": float(np.mean(np.std(eta, axis=1, ddof=1))),
        "mean_eta_simulator": float(eta.mean()),
        "mean_eta_surrogate": float(mean.mean()),
        "return_simulator_mean": float(sim_returns.mean()),
        "return_surrogate_mean": float(sur_returns.mean()),
        "return_rmse": float(np.sqrt(np.mean((sur_returns.mean(axis=1) - sim_returns) ** 2))),
        "return_sd_surrogate": float(np.mean(sur_returns.std(axis=1, ddof=1))),
        "return_spearman": float(stats.spearmanr(sim_returns, sur_returns.mean(axis=1)).statistic),
        "behaviours": by_behaviour,
        "behaviour_order_simulator": order_sim,
        "behaviour_order_surrogate": order_sur,
        "behaviour_order_kendall": kendall,
    }


def evaluate(
    model: SurrogateModel, held: list[Episode], settings: dict[str, Any], samples: int, seed: int
) -> dict[str, Any]:
    """The held-out metrics of the module docstring."""
    return metrics_of(predict(model, held, settings, samples, seed))


def paired_difference(a: dict[str, Any], b: dict[str, Any], seed: int, draws: int = 4000) -> dict[str, float]:
    """Rollout RMSE of eta_r, route ``a`` minus route ``b``, on the same episodes, with a 95% percentile
    bootstrap over episodes."""
    mse_a = np.mean((a["rollouts"].mean(axis=1) - a["eta"]) ** 2, axis=1)
    mse_b = np.mean((b["rollouts"].mean(axis=1) - b["eta"]) ** 2, axis=1)
    rng = np.random.default_rng(seed)
    idx = rng.integers(len(mse_a), size=(draws, len(mse_a)))
    diffs = np.sqrt(mse_a[idx].mean(axis=1)) - np.sqrt(mse_b[idx].mean(axis=1))
    low, high = np.quantile(diffs, [0.025, 0.975])
    return {
        "difference": float(np.sqrt(mse_a.mean()) - np.sqrt(mse_b.mean())),
        "low": float(low),
        "high": float(high),
    }


def choose(metrics: dict[str, dict[str, Any]], key: str = "held_out") -> tuple[str, str]:
    """The route to keep and why (``--keep auto``, module docstring), on the metrics under ``key``
    (``cross_validated`` when the folds were run)."""
    routes = sorted(metrics, key=lambda r: metrics[r][key]["rollout_rmse_eta"])
    best = routes[0]
    if len(routes) == 1:
        return best, "the only route fitted"

    def calibrated(r: str) -> bool:
        return 1 / 1.5 <= metrics[r][key]["spread_ratio"] <= 1.5

    other = routes[1]
    rmse = {r: metrics[r][key]["rollout_rmse_eta"] for r in routes}
    if not calibrated(best) and calibrated(other):
        return other, (
            f"{best} has the lower rollout error of eta_r ({rmse[best]:.3f} against {rmse[other]:.3f}) "
            f"but its spread is off by more than 1.5x; {other}'s is not"
        )
    return (
        best,
        f"lowest rollout error of eta_r on the held-out episodes ({key}: {rmse[best]:.3f} against "
        f"{rmse[other]:.3f})",
    )


def data_path(path: Path) -> str:
    """Where the fit's data lie, as recorded with the weights: relative to the repository root when inside
    it (``results/surrogate_data``, the same in any clone or worktree), else absolute."""
    resolved = path.resolve()
    try:
        return resolved.relative_to(ROOT).as_posix()
    except ValueError:
        return str(resolved)


def git_commit() -> str:
    try:
        return subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0], allow_abbrev=False)
    parser.add_argument("data", type=Path, help="folder of scripts/surrogate_data.py")
    parser.add_argument("--out", required=True, type=Path, help="the kept model (.npz); metrics beside it")
    parser.add_argument(
        "--routes",
        default=None,
        help="routes to fit (default both; tracking data: ensemble, the only route that sees the direction)",
    )
    parser.add_argument("--keep", default="auto", help="auto (module docstring) or a route")
    parser.add_argument("--reason", default="chosen by --keep", help="why --keep names a route (recorded)")
    parser.add_argument("--seeds", default=None, help="episode seeds to use, e.g. 0-49 (default: every file)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the fit (starts, inits, batches)")
    parser.add_argument("--holdout-mod", type=int, default=5, help="hold out seeds s %% M == M - 1")
    parser.add_argument("--samples", type=int, default=32, help="rollouts per held-out episode")
    parser.add_argument("--starts", type=int, default=4, help="starts of the lambda fit")
    parser.add_argument("--members", type=int, default=5)
    parser.add_argument("--hidden", type=int, default=64)
    parser.add_argument("--max-epochs", type=int, default=400)
    parser.add_argument("--patience", type=int, default=25)
    parser.add_argument(
        "--cross-validate",
        action="store_true",
        help="also fit on the other folds (seed %% M == r), pool all held-out episodes, choose on them",
    )
    parser.add_argument("--save-all", action="store_true", help="also write FILE.<route>.npz for each route")
    return parser


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.holdout_mod < 2:
        parser.error("--holdout-mod must be >= 2")
    settings = data_settings(args.data)
    episodes = load_episodes(args.data, settings["control_interval"], settings["max_piece"])
    try:
        direction = has_directions(episodes)
    except ValueError as error:
        parser.error(f"{args.data}: {error}")
    tracking = settings.get("task") == "tracking"
    if tracking and episodes and not direction:
        parser.error(f"{args.data}: tracking episodes without their fields' directions")
    route_text = args.routes if args.routes is not None else ("ensemble" if tracking else "lambda,ensemble")
    routes = [r.strip() for r in route_text.split(",") if r.strip()]
    if not routes or any(r not in ROUTES for r in routes):
        parser.error(f"--routes must be a list of {', '.join(ROUTES)}, got {route_text!r}")
    if tracking and "lambda" in routes:
        parser.error(
            "--routes: the lambda model knows fields along y only; tracking data (a turning field) are "
            "fitted by the ensemble with the direction block (--routes ensemble)"
        )
    if args.keep != "auto" and args.keep not in routes:
        parser.error(f"--keep must be auto or one of the fitted routes {routes}, got {args.keep!r}")
    if args.seeds is not None:
        try:
            wanted = set(sim.parse_seeds(args.seeds))
        except ValueError as error:
            parser.error(f"--seeds: {error}")
        episodes = [e for e in episodes if e.seed in wanted]
    fit, held = split_episodes(episodes, args.holdout_mod)
    if len(fit) < 2 or not held:
        parser.exit(
            2,
            f"fit_surrogate.py: error: {len(episodes)} episodes in {args.data}: too few to fit and hold "
            "out\n",
        )
    common = common_arrays(episodes, fit)
    provenance = {
        "data": data_path(args.data),
        "episodes": len(episodes),
        "fit_episodes": len(fit),
        "held_out_episodes": [e.seed for e in held],
        "command": shlex.join(
            ["python", "scripts/fit_surrogate.py", *(argv if argv is not None else sys.argv[1:])]
        ),
        "seed": args.seed,
        "holdout": f"seed % {args.holdout_mod} == {args.holdout_mod - 1}",
        "source_commit": git_commit(),
        "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "start_frames": "the first frame of every data episode, one per train start state",
    }
    models: dict[str, SurrogateModel] = {}
    metrics: dict[str, dict[str, Any]] = {}
    predictions: dict[str, list[dict[str, Any]]] = {route: [] for route in routes}
    mod = args.holdout_mod
    folds = [mod - 1] + (list(range(mod - 1)) if args.cross_validate else [])
    for fold in folds:
        fold_fit = [e for e in episodes if e.seed % mod != fold]
        fold_held = [e for e in episodes if e.seed % mod == fold]
        if not fold_held or len(fold_fit) < 2:
            continue
        fold_common = common if fold == mod - 1 else common_arrays(episodes, fold_fit)
        for route in routes:
            tic = time.process_time()
            if route == "lambda":
                arrays, info = fit_lambda(fold_fit, args.seed, args.starts)
                model: SurrogateModel = LambdaModel({**fold_common, **arrays}, {"settings": settings})
            else:
                arrays, info = fit_ensemble(
                    fold_fit, args.seed, args.members, args.hidden, args.max_epochs, args.patience, direction
                )
                meta: dict[str, Any] = {"settings": settings}
                if direction:
                    meta["direction_inputs"] = True
                model = EnsembleModel({**fold_common, **arrays}, meta)
            info["fit_cpu_seconds"] = round(time.process_time() - tic, 1)
            prediction = predict(model, fold_held, settings, args.samples, args.seed)
            predictions[route].append(prediction)
            if fold == mod - 1:
                held_out = metrics_of(prediction)
                metrics[route] = {"fit": info, "held_out": held_out}
                models[route] = model
                print(json.dumps({"route": route, **held_out}, default=float))
            else:
                print(json.dumps({"route": route, "fold": fold, **metrics_of(prediction)}, default=float))
            sys.stdout.flush()
    key = "held_out"
    comparison: dict[str, Any] = {}
    if args.cross_validate:
        key = "cross_validated"
        for route in routes:
            metrics[route]["cross_validated"] = metrics_of(pooled(predictions[route]))
        if len(routes) == 2:
            a, b = routes
            comparison = {
                f"rollout_rmse_eta_{a}_minus_{b}": paired_difference(
                    pooled(predictions[a]), pooled(predictions[b]), args.seed
                )
            }
    kept, reason = choose(metrics, key) if args.keep == "auto" else (args.keep, args.reason)
    summary = {
        **provenance,
        "settings": settings,
        "routes": metrics,
        "comparison": comparison,
        "kept": kept,
        "reason": reason,
    }
    provenance = {**provenance, "kept": kept, "reason": reason, "comparison": comparison}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    for route, model in models.items():
        model.metadata = {**provenance, "settings": settings, "route": route, "metrics": metrics[route]}
        if model.direction:
            model.metadata["direction_inputs"] = True
        if route == kept:
            model.save(args.out)
        if args.save_all:
            model.save(args.out.with_suffix(f".{route}.npz"))
    args.out.with_suffix(".metrics.json").write_text(json.dumps(summary, indent=1, default=float) + "\n")
    print(json.dumps({"kept": kept, "reason": reason}))
    return summary


if __name__ == "__main__":
    main()
