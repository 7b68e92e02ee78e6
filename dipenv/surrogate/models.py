"""The surrogate's dynamics: numpy inference of the fitted models (no torch at step time).

Two model kinds, one interface (:class:`SurrogateModel`), stored as one ``.npz`` each (arrays plus a JSON
``metadata`` string with the provenance and the env settings of the data):

* :class:`EnsembleModel` (``kind = "ensemble"``): a probabilistic ensemble of small MLPs (PETS, Chua et
  al. 2018; MBPO, Janner et al. 2019). Each member maps the frame's dynamic part, the field of this and the
  previous interval and the interval's rates (:func:`dipenv.surrogate.features.mlp_inputs`) to a Gaussian
  (mean and log-variance, soft-bounded) of the change of the dynamic part over the interval. A rollout
  draws one member per episode and samples each step from its Gaussian. A model fitted on episodes with
  a turning field (``ViscosityTracking``) also sees the direction block of both intervals (metadata
  ``direction_inputs``: true; :attr:`EnsembleModel.direction`); one fitted without it does not, and its
  inputs and outputs are those of the version before the block existed, bit for bit.
* :class:`LambdaModel` (``kind = "lambda"``): structural kinetics (Moore 1959; Mewis & Wagner, *Adv.
  Colloid Interface Sci.* 147-148, 2009). Two structure variables relax in strain toward steady values
  set by the instantaneous Mason number ``Mn = rate x Mn_ref``: ``lambda_F``, the field's layered
  structure (0 without a field, ``1 / (1 + (Mn / Mn_F)^p_F)`` under it; built over ``gamma_F_on`` strains,
  lost over ``gamma_F_off``), and ``lambda_T``, the field-free, shear-thickened contact structure (1
  without a field, ``1 / (1 + (Mn_T / Mn)^p_T)`` under it; broken over ``gamma_T_on``, rebuilt over
  ``gamma_T_off``). Over each piece of an interval they relax exactly (exponentials in strain); the
  interval's means and end values, the field-stress term ``E = Mn^-q`` (field on) and ``log10`` of the
  mean rate make the features :data:`LAMBDA_FEATURES`, and every output (``eta_r`` in linear units, the
  other 11 dynamic entries in observation units) is linear in them. The noise is a heteroscedastic
  AR(1) per output with correlated innovations: ``r_t = rho(strain) r_{t-1} + sigma(lambda) L xi``,
  ``rho = exp(-(a + b strain))``; the first residual is the start frame's own.

Both clip their outputs into the range of the data they were fitted on (``low``, ``high``, with a margin).
"""

from __future__ import annotations

import json
import math
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from dipenv.surrogate.features import (
    N_DIRECTION_INPUTS,
    N_DYNAMIC,
    N_MLP_INPUTS,
    IntervalTable,
    inverse_signed_log,
    mlp_inputs,
    mlp_inputs_into,
    signed_log,
)

LAMBDA_PARAMETERS = (
    "log10_mason_f",
    "p_f",
    "log10_mason_t",
    "p_t",
    "gamma_f_on",
    "gamma_f_off",
    "gamma_t_on",
    "gamma_t_off",
    "q",
)
"""The nonlinear parameters of :class:`LambdaModel` (the linear read-out is solved for them)."""

LAMBDA_FEATURES = (
    "one",
    "mean_lambda_f",
    "mean_lambda_t",
    "mean_lambda_f_E",
    "mean_E",
    "end_lambda_f",
    "end_lambda_t",
    "on",
    "log10_rate",
    "mean_lambda_f_log10_rate",
    "mean_lambda_t_log10_rate",
)
"""Features of one interval that the outputs of :class:`LambdaModel` are linear in."""

N_LAMBDA_FEATURES = len(LAMBDA_FEATURES)

DEFAULT_MODEL = "surrogate_v0.npz"
"""The shipped model under ``dipenv/data/``."""


def _expm1_ratio(x: np.ndarray) -> np.ndarray:
    """``(1 - exp(-x)) / x`` with the limit 1 at ``x = 0``."""
    small = x < 1e-8
    safe = np.where(small, 1.0, x)
    return np.where(small, 1.0 - 0.5 * x, -np.expm1(-safe) / safe)


def lambda_interval(
    theta: np.ndarray,
    lam_f: np.ndarray,
    lam_t: np.ndarray,
    mason: np.ndarray,
    piece_rate: np.ndarray,
    piece_time: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Advance the structure variables over one interval (batched).

    Args:
        theta: (9,) the parameters :data:`LAMBDA_PARAMETERS` in natural units.
        lam_f, lam_t: (B,) structure at the interval's start.
        mason: (B,) ``Mn_ref`` (``inf``: off).
        piece_rate, piece_time: (B, P) the interval's pieces (:class:`IntervalTable`).

    Returns:
        ``(lam_f, lam_t, features, strain)``: the end values, the (B, 11) features
        :data:`LAMBDA_FEATURES`, and the (B,) strain of the interval.
    """
    log_mf, p_f, log_mt, p_t, g_f_on, g_f_off, g_t_on, g_t_off, q = (float(v) for v in theta)
    on = np.isfinite(mason)
    mref = np.where(on, mason, 1.0)
    total_time = piece_time.sum(axis=1)
    sum_f = np.zeros_like(lam_f)
    sum_t = np.zeros_like(lam_f)
    sum_fe = np.zeros_like(lam_f)
    sum_e = np.zeros_like(lam_f)
    strain = np.zeros_like(lam_f)
    g_f = np.where(on, g_f_on, g_f_off)
    g_t = np.where(on, g_t_on, g_t_off)
    for j in range(piece_rate.shape[1]):
        dt = piece_time[:, j]
        if not np.any(dt > 0.0):
            break
        rate = np.where(dt > 0.0, piece_rate[:, j], 1.0)
        log_mn = np.log10(mref * rate)
        ss_f = np.where(on, 1.0 / (1.0 + 10.0 ** np.clip(p_f * (log_mn - log_mf), -30, 30)), 0.0)
        ss_t = np.where(on, 1.0 / (1.0 + 10.0 ** np.clip(p_t * (log_mt - log_mn), -30, 30)), 1.0)
        field = np.where(on, 10.0 ** np.clip(-q * log_mn, -30, 30), 0.0)
        d_strain = rate * dt
        x_f = d_strain / g_f
        x_t = d_strain / g_t
        mean_f = ss_f + (lam_f - ss_f) * _expm1_ratio(x_f)
        mean_t = ss_t + (lam_t - ss_t) * _expm1_ratio(x_t)
        lam_f = ss_f + (lam_f - ss_f) * np.exp(-x_f)
        lam_t = ss_t + (lam_t - ss_t) * np.exp(-x_t)
        sum_f += dt * mean_f
        sum_t += dt * mean_t
        sum_fe += dt * mean_f * field
        sum_e += dt * field
        strain += d_strain
    mean_rate = strain / total_time
    log_rate = np.log10(mean_rate)
    mf, mt = sum_f / total_time, sum_t / total_time
    features = np.stack(
        [
            np.ones_like(mf),
            mf,
            mt,
            sum_fe / total_time,
            sum_e / total_time,
            lam_f,
            lam_t,
            on.astype(np.float64),
            log_rate,
            mf * log_rate,
            mt * log_rate,
        ],
        axis=1,
    )
    return lam_f, lam_t, features, strain


def lambda_interval_scalar(
    theta: tuple[float, ...],
    lam_f: float,
    lam_t: float,
    mason: float,
    parts: tuple[tuple[float, float], ...],
    features: np.ndarray,
) -> tuple[float, float, float]:
    """:func:`lambda_interval` for one episode in plain floats (the env's step; no array temporaries).

    Writes the 11 features into ``features`` and returns ``(lam_f, lam_t, strain)``.
    """
    log_mf, p_f, log_mt, p_t, g_f_on, g_f_off, g_t_on, g_t_off, q = theta
    on = not math.isinf(mason)
    g_f, g_t = (g_f_on, g_t_on) if on else (g_f_off, g_t_off)
    sum_f = sum_t = sum_fe = sum_e = strain = total = 0.0
    for rate, dt in parts:
        if on:
            log_mn = math.log10(mason * rate)
            ss_f = 1.0 / (1.0 + 10.0 ** min(max(p_f * (log_mn - log_mf), -30.0), 30.0))
            ss_t = 1.0 / (1.0 + 10.0 ** min(max(p_t * (log_mt - log_mn), -30.0), 30.0))
            field = 10.0 ** min(max(-q * log_mn, -30.0), 30.0)
        else:
            ss_f, ss_t, field = 0.0, 1.0, 0.0
        d_strain = rate * dt
        x_f, x_t = d_strain / g_f, d_strain / g_t
        ratio_f = 1.0 - 0.5 * x_f if x_f < 1e-8 else -math.expm1(-x_f) / x_f
        ratio_t = 1.0 - 0.5 * x_t if x_t < 1e-8 else -math.expm1(-x_t) / x_t
        mean_f = ss_f + (lam_f - ss_f) * ratio_f
        mean_t = ss_t + (lam_t - ss_t) * ratio_t
        lam_f = ss_f + (lam_f - ss_f) * math.exp(-x_f)
        lam_t = ss_t + (lam_t - ss_t) * math.exp(-x_t)
        sum_f += dt * mean_f
        sum_t += dt * mean_t
        sum_fe += dt * mean_f * field
        sum_e += dt * field
        strain += d_strain
        total += dt
    log_rate = math.log10(strain / total)
    mf, mt = sum_f / total, sum_t / total
    features[0] = 1.0
    features[1] = mf
    features[2] = mt
    features[3] = sum_fe / total
    features[4] = sum_e / total
    features[5] = lam_f
    features[6] = lam_t
    features[7] = 1.0 if on else 0.0
    features[8] = log_rate
    features[9] = mf * log_rate
    features[10] = mt * log_rate
    return lam_f, lam_t, strain


def lambda_trajectories(
    theta: np.ndarray, masons: np.ndarray, tables: list[IntervalTable]
) -> tuple[np.ndarray, np.ndarray]:
    """(E, T, 11) features and (E, T) strains of E episodes' structure trajectories from the start state
    (``lambda_F = 0``, ``lambda_T = 1``) under the fields ``masons`` (E, T)."""
    n_ep, steps = masons.shape
    rate = np.stack([t.piece_rate for t in tables])
    time = np.stack([t.piece_time for t in tables])
    lam_f, lam_t = np.zeros(n_ep), np.ones(n_ep)
    phis = np.empty((n_ep, steps, N_LAMBDA_FEATURES))
    strains = np.empty((n_ep, steps))
    for k in range(steps):
        lam_f, lam_t, phis[:, k], strains[:, k] = lambda_interval(
            theta, lam_f, lam_t, masons[:, k], rate[:, k], time[:, k]
        )
    return phis, strains


def initial_lambda_features(batch: int) -> np.ndarray:
    """(B, 11) features of the start state: pre-sheared without a field at rate 1 (``lambda_F = 0``,
    ``lambda_T = 1``)."""
    phi = np.zeros((batch, N_LAMBDA_FEATURES))
    phi[:, 0] = 1.0
    phi[:, 2] = 1.0
    phi[:, 6] = 1.0
    return phi


def to_output_space(dynamic: np.ndarray) -> np.ndarray:
    """Dynamic frame part -> the lambda model's output space (``eta_r`` linear instead of slog)."""
    out = np.array(dynamic, dtype=np.float64, copy=True)
    out[..., 0] = inverse_signed_log(out[..., 0])
    return out


def to_dynamic(outputs: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_output_space`."""
    out = np.array(outputs, dtype=np.float64, copy=True)
    out[..., 0] = signed_log(out[..., 0])
    return out


class SurrogateModel:
    """A fitted dynamics model of the frames' dynamic part of ``ThickeningControl`` (or, with
    :attr:`direction`, of ``ViscosityTracking``; see the module docstring).

    Attributes:
        metadata: provenance, env settings of the data (``settings``), fit metrics.
        start_frames: (K, 12) dynamic parts of the data's initial frames; ``start_indices``: (K,) their
            train start states.
        low, high: (12,) clip of the outputs (dynamic-part units).
    """

    kind = ""
    direction: bool = False
    """Whether the model sees the field's direction (the direction block of
    :mod:`dipenv.surrogate.features`); a model without it knows only fields along ``y``."""

    def __init__(self, arrays: dict[str, np.ndarray], metadata: dict[str, Any]) -> None:
        self.arrays = arrays
        self.metadata = metadata
        self.start_frames = np.asarray(arrays["start_frames"], dtype=np.float64)
        self.start_indices = np.asarray(arrays["start_indices"], dtype=np.int64)
        self.low = np.asarray(arrays["low"], dtype=np.float64)
        self.high = np.asarray(arrays["high"], dtype=np.float64)

    @property
    def settings(self) -> dict[str, Any]:
        """The env settings of the data the model was fitted on."""
        return dict(self.metadata.get("settings", {}))

    # -- one episode (the environment) ---------------------------------------------------------------------
    def begin(self, frame: np.ndarray, rng: np.random.Generator) -> None:
        """Start an episode from the dynamic part ``frame`` (12,)."""
        raise NotImplementedError

    def step(
        self,
        previous_mason: float,
        mason: float,
        table: IntervalTable,
        k: int,
        rng: np.random.Generator,
        previous_direction: np.ndarray | None = None,
        direction: np.ndarray | None = None,
    ) -> np.ndarray:
        """Sample interval ``k``'s dynamic frame part (12,; a buffer reused by the next call). The
        directions (unit vectors of the previous and this interval's field; ``None``: ``y``) are read only
        by a model with :attr:`direction`."""
        raise NotImplementedError

    # -- batches (fit and checks) --------------------------------------------------------------------------
    def rollout(
        self,
        frames: np.ndarray,
        masons: np.ndarray,
        tables: list[IntervalTable],
        rng: np.random.Generator,
        samples: int,
        previous: np.ndarray | None = None,
        directions: np.ndarray | None = None,
        previous_direction: np.ndarray | None = None,
    ) -> np.ndarray:
        """Open-loop rollouts: (E, samples, T, 12) sampled dynamic parts of E episodes from their start
        frames (E, 12) under the fields ``masons`` (E, T), over the first T intervals of each table
        (:meth:`IntervalTable.window` starts one mid-episode). ``previous`` (E,): the field ``Mn_ref``
        of the interval before the first (default: off, an episode's start). ``directions`` (E, T, 3) and
        ``previous_direction`` (E, 3): the fields' directions (default ``y``; read only by a model with
        :attr:`direction`)."""
        raise NotImplementedError

    def one_step(
        self,
        dynamic: np.ndarray,
        masons: np.ndarray,
        tables: list[IntervalTable],
        directions: np.ndarray | None = None,
    ) -> np.ndarray:
        """(E, T, 12) the predicted mean of each interval's dynamic part given the observed frames before
        it (``dynamic``: (E, T + 1, 12), the episodes' observed dynamic parts; ``directions`` (E, T, 3):
        the fields' directions, default ``y``, read only by a model with :attr:`direction`)."""
        raise NotImplementedError

    def save(self, path: str | Path) -> None:
        """Write the model (arrays and the JSON metadata) to ``path``."""
        meta = {**self.metadata, "kind": self.kind}
        if self.direction:  # written only when set: a model without the block is saved as before
            meta["direction_inputs"] = True
        payload: dict[str, Any] = {"metadata": np.array(json.dumps(meta)), **self.arrays}
        np.savez_compressed(path, **payload)


def _silu(x: np.ndarray) -> np.ndarray:
    return x / (1.0 + np.exp(-x))


def _softbound(logvar: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Soft bounds of a log-variance (PETS): ``high - softplus(high - v)``, then ``low + softplus(.)``."""
    logvar = high - np.logaddexp(0.0, high - logvar)
    return low + np.logaddexp(0.0, logvar - low)


class EnsembleModel(SurrogateModel):
    """Probabilistic ensemble of MLPs (arrays ``w1 b1 w2 b2 w3 b3`` with a leading member axis, ``x_mean
    x_std`` input scaling, ``y_mean y_std`` output scaling of the change of the dynamic part,
    ``max_logvar min_logvar``). Its inputs carry the direction block when the metadata say
    ``direction_inputs: true`` (:attr:`direction`); ``w1`` must have that many rows."""

    kind = "ensemble"

    def __init__(self, arrays: dict[str, np.ndarray], metadata: dict[str, Any]) -> None:
        super().__init__(arrays, metadata)
        a = {k: np.asarray(v, dtype=np.float64) for k, v in arrays.items() if k not in ("start_indices",)}
        self.w = [a["w1"], a["w2"], a["w3"]]
        self.b = [a["b1"], a["b2"], a["b3"]]
        self.members = int(self.w[0].shape[0])
        self.direction = bool(metadata.get("direction_inputs", False))
        inputs = N_MLP_INPUTS + (N_DIRECTION_INPUTS if self.direction else 0)
        if self.w[0].shape[1] != inputs or self.w[2].shape[2] != 2 * N_DYNAMIC:
            raise ValueError(
                f"ensemble weights of shapes {[w.shape for w in self.w]} do not fit the {inputs} inputs "
                f"(direction_inputs: {self.direction})"
            )
        self.x_mean, self.x_std = a["x_mean"], a["x_std"]
        self.y_mean, self.y_std = a["y_mean"], a["y_std"]
        self.max_logvar, self.min_logvar = a["max_logvar"], a["min_logvar"]
        self._member = 0
        self._weights = ([w[0] for w in self.w], [b[0] for b in self.b])
        self._frame = np.zeros(N_DYNAMIC)
        self._x = np.zeros(inputs)

    def _forward(self, x: np.ndarray, member: int | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and variance of the scaled change; ``x`` (B, I) unscaled, ``member`` int or (B,)."""
        h = (x - self.x_mean) / self.x_std
        if isinstance(member, int):
            for layer in range(2):
                h = _silu(h @ self.w[layer][member] + self.b[layer][member])
            out = h @ self.w[2][member] + self.b[2][member]
        else:  # one matrix product per member over its rows (gathering a weight matrix per row is slow)
            member = np.asarray(member)
            out = np.empty((h.shape[0], self.w[2].shape[2]))
            for m in np.unique(member):
                rows = member == m
                hm = h[rows]
                for layer in range(2):
                    hm = _silu(hm @ self.w[layer][m] + self.b[layer][m])
                out[rows] = hm @ self.w[2][m] + self.b[2][m]
        mean, logvar = out[..., :N_DYNAMIC], out[..., N_DYNAMIC:]
        return mean, np.exp(_softbound(logvar, self.min_logvar, self.max_logvar))

    def begin(self, frame: np.ndarray, rng: np.random.Generator) -> None:
        self._member = int(rng.integers(self.members))
        m = self._member
        self._weights = ([w[m] for w in self.w], [b[m] for b in self.b])
        self._frame[:] = frame

    def step(
        self,
        previous_mason: float,
        mason: float,
        table: IntervalTable,
        k: int,
        rng: np.random.Generator,
        previous_direction: np.ndarray | None = None,
        direction: np.ndarray | None = None,
    ) -> np.ndarray:
        x = mlp_inputs_into(
            self._x,
            self._frame,
            previous_mason,
            mason,
            float(table.rate_start[k]),
            float(table.rate_mean[k]),
            float(table.rate_end[k]),
            previous_direction,
            direction,
        )
        w, b = self._weights
        h = (x - self.x_mean) / self.x_std
        for layer in range(2):
            h = h @ w[layer] + b[layer]
            h = h / (1.0 + np.exp(-h))
        out = h @ w[2] + b[2]
        logvar = _softbound(out[N_DYNAMIC:], self.min_logvar, self.max_logvar)
        change = out[:N_DYNAMIC] + np.exp(0.5 * logvar) * rng.standard_normal(N_DYNAMIC)
        frame = self._frame
        frame += self.y_mean + self.y_std * change
        np.clip(frame, self.low, self.high, out=frame)
        return frame

    def _inputs(
        self,
        frames: np.ndarray,
        masons: np.ndarray,
        tables: list[IntervalTable],
        k: int,
        directions: np.ndarray | None = None,
    ) -> np.ndarray:
        previous = np.array([m[k - 1] if k > 0 else np.inf for m in masons])
        start = np.array([t.rate_start[k] for t in tables])
        mean = np.array([t.rate_mean[k] for t in tables])
        end = np.array([t.rate_end[k] for t in tables])
        before, now = _directions_at(directions, k) if self.direction else (None, None)
        return mlp_inputs(
            frames, previous, masons[:, k], start, mean, end, before, now, direction_block=self.direction
        )

    def rollout(
        self,
        frames: np.ndarray,
        masons: np.ndarray,
        tables: list[IntervalTable],
        rng: np.random.Generator,
        samples: int,
        previous: np.ndarray | None = None,
        directions: np.ndarray | None = None,
        previous_direction: np.ndarray | None = None,
    ) -> np.ndarray:
        n_ep, steps = masons.shape
        members = rng.integers(self.members, size=n_ep * samples)
        rep_masons = np.repeat(masons, samples, axis=0)
        first = np.full(n_ep, np.inf) if previous is None else np.asarray(previous, dtype=np.float64)
        before = np.concatenate([np.repeat(first, samples)[:, None], rep_masons[:, :-1]], axis=1)
        start, mean_rate, end = (
            np.repeat(np.stack([getattr(t, name)[:steps] for t in tables]), samples, axis=0)
            for name in ("rate_start", "rate_mean", "rate_end")
        )
        if self.direction:
            dirs = _y_axes((n_ep, steps)) if directions is None else np.asarray(directions, dtype=np.float64)
            first_dir = (
                _y_axes((n_ep,)) if previous_direction is None else np.asarray(previous_direction, float)
            )
            rep_dirs = np.repeat(dirs, samples, axis=0)
            before_dirs = np.concatenate(
                [np.repeat(first_dir, samples, axis=0)[:, None], rep_dirs[:, :-1]], axis=1
            )
        current = np.repeat(np.asarray(frames, dtype=np.float64), samples, axis=0)
        out = np.empty((n_ep * samples, steps, N_DYNAMIC))
        for k in range(steps):
            dir_before, dir_now = (before_dirs[:, k], rep_dirs[:, k]) if self.direction else (None, None)
            x = mlp_inputs(
                current,
                before[:, k],
                rep_masons[:, k],
                start[:, k],
                mean_rate[:, k],
                end[:, k],
                dir_before,
                dir_now,
                direction_block=self.direction,
            )
            mean, var = self._forward(x, members)
            change = mean + np.sqrt(var) * rng.standard_normal(mean.shape)
            current = np.clip(current + self.y_mean + self.y_std * change, self.low, self.high)
            out[:, k] = current
        return out.reshape(n_ep, samples, steps, N_DYNAMIC)

    def one_step(
        self,
        dynamic: np.ndarray,
        masons: np.ndarray,
        tables: list[IntervalTable],
        directions: np.ndarray | None = None,
    ) -> np.ndarray:
        n_ep, steps = masons.shape
        out = np.empty((n_ep, steps, N_DYNAMIC))
        for k in range(steps):
            x = self._inputs(dynamic[:, k], masons, tables, k, directions)
            means = [self._forward(x, m)[0] for m in range(self.members)]
            change = np.mean(means, axis=0)
            out[:, k] = np.clip(dynamic[:, k] + self.y_mean + self.y_std * change, self.low, self.high)
        return out


def _y_axes(shape: tuple[int, ...]) -> np.ndarray:
    """``shape + (3,)`` copies of ``y`` (the direction of a model given none)."""
    return np.broadcast_to(np.array([0.0, 1.0, 0.0]), (*shape, 3)).copy()


def _directions_at(directions: np.ndarray | None, k: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The directions (E, 3) of interval ``k - 1`` and of ``k`` of ``directions`` (E, T, 3); ``None``
    where there is none (before the first interval, or no ``directions``), which
    :func:`dipenv.surrogate.features.mlp_inputs` reads as ``y``."""
    if directions is None:
        return None, None
    dirs = np.asarray(directions, dtype=np.float64)
    return (dirs[:, k - 1] if k > 0 else None), dirs[:, k]


class LambdaModel(SurrogateModel):
    """Structural-kinetics model (arrays ``theta`` (9,) :data:`LAMBDA_PARAMETERS`, ``readout`` (11, 12),
    ``rho_a rho_b`` (12,), ``var_coef`` (3, 12) and ``var_floor`` (12,), ``chol`` (12, 12)). It knows
    fields along ``y`` only: directions passed to it are ignored."""

    kind = "lambda"

    def __init__(self, arrays: dict[str, np.ndarray], metadata: dict[str, Any]) -> None:
        super().__init__(arrays, metadata)
        self.theta = np.asarray(arrays["theta"], dtype=np.float64)
        self.readout = np.asarray(arrays["readout"], dtype=np.float64)
        self.rho_a = np.asarray(arrays["rho_a"], dtype=np.float64)
        self.rho_b = np.asarray(arrays["rho_b"], dtype=np.float64)
        self.var_coef = np.asarray(arrays["var_coef"], dtype=np.float64)
        self.var_floor = np.asarray(arrays["var_floor"], dtype=np.float64)
        self.chol = np.asarray(arrays["chol"], dtype=np.float64)
        self._theta = tuple(float(v) for v in self.theta)
        self._lam = (0.0, 1.0)
        self._residual = np.zeros(N_DYNAMIC)
        self._phi = np.zeros(N_LAMBDA_FEATURES)
        self._out = np.zeros(N_DYNAMIC)
        self._frame = np.zeros(N_DYNAMIC)

    def mean_outputs(self, features: np.ndarray) -> np.ndarray:
        """(..., 12) outputs (output space) of the deterministic part."""
        return features @ self.readout

    def rho(self, strain: np.ndarray) -> np.ndarray:
        """(..., 12) AR(1) coefficient of each output for intervals of ``strain``."""
        return np.exp(-(self.rho_a + self.rho_b * np.asarray(strain)[..., None]))

    def sigma(self, features: np.ndarray) -> np.ndarray:
        """(..., 12) innovation sd of each output."""
        var = features[..., :3] @ self.var_coef
        return np.sqrt(np.maximum(var, self.var_floor))

    def _noise(self, features: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        xi = rng.standard_normal((features.shape[0], N_DYNAMIC))
        return self.sigma(features) * (xi @ self.chol.T)

    def begin(self, frame: np.ndarray, rng: np.random.Generator) -> None:
        self._lam = (0.0, 1.0)
        phi0 = initial_lambda_features(1)
        self._residual[:] = (to_output_space(np.asarray(frame)[None, :]) - self.mean_outputs(phi0))[0]

    def step(
        self,
        previous_mason: float,
        mason: float,
        table: IntervalTable,
        k: int,
        rng: np.random.Generator,
        previous_direction: np.ndarray | None = None,
        direction: np.ndarray | None = None,
    ) -> np.ndarray:
        phi = self._phi
        lam_f, lam_t, strain = lambda_interval_scalar(
            self._theta, self._lam[0], self._lam[1], mason, table.parts[k], phi
        )
        self._lam = (lam_f, lam_t)
        residual = self._residual
        residual *= np.exp(-(self.rho_a + self.rho_b * strain))
        sigma = np.sqrt(np.maximum(phi[:3] @ self.var_coef, self.var_floor))
        residual += sigma * (self.chol @ rng.standard_normal(N_DYNAMIC))
        out = self._out
        np.dot(phi, self.readout, out=out)
        out += residual
        eta = out[0]
        out[0] = math.copysign(math.log10(1.0 + abs(eta)), eta)
        np.clip(out, self.low, self.high, out=self._frame)
        return self._frame

    def deterministic(self, masons: np.ndarray, tables: list[IntervalTable]) -> tuple[np.ndarray, np.ndarray]:
        """(E, T, 11) features and (E, T) strains of the structure trajectories under ``masons`` (E, T)."""
        return lambda_trajectories(self.theta, masons, tables)

    def rollout(
        self,
        frames: np.ndarray,
        masons: np.ndarray,
        tables: list[IntervalTable],
        rng: np.random.Generator,
        samples: int,
        previous: np.ndarray | None = None,
        directions: np.ndarray | None = None,
        previous_direction: np.ndarray | None = None,
    ) -> np.ndarray:
        if previous is not None and np.isfinite(previous).any():
            raise ValueError(
                "the lambda model's rollout starts at an episode's start (structure of a field-free "
                "pre-sheared state): its structure variables are not in the frame, so it cannot start "
                "mid-episode after a field"
            )
        n_ep, steps = masons.shape
        phis, strains = self.deterministic(masons, tables)
        mean = self.mean_outputs(phis)  # (E, T, 12)
        residual = np.repeat(
            to_output_space(frames) - self.mean_outputs(initial_lambda_features(n_ep)), samples, axis=0
        )
        out = np.empty((n_ep * samples, steps, N_DYNAMIC))
        for k in range(steps):
            phi = np.repeat(phis[:, k], samples, axis=0)
            residual = self.rho(np.repeat(strains[:, k], samples)) * residual + self._noise(phi, rng)
            out[:, k] = np.clip(
                to_dynamic(np.repeat(mean[:, k], samples, axis=0) + residual), self.low, self.high
            )
        return out.reshape(n_ep, samples, steps, N_DYNAMIC)

    def one_step(
        self,
        dynamic: np.ndarray,
        masons: np.ndarray,
        tables: list[IntervalTable],
        directions: np.ndarray | None = None,
    ) -> np.ndarray:
        n_ep, steps = masons.shape
        phis, strains = self.deterministic(masons, tables)
        mean = self.mean_outputs(phis)
        observed = to_output_space(dynamic)
        previous = np.concatenate(
            [self.mean_outputs(initial_lambda_features(n_ep))[:, None], mean[:, :-1]], axis=1
        )
        predicted = mean + self.rho(strains) * (observed[:, :-1] - previous)
        return np.clip(to_dynamic(predicted), self.low, self.high)


KINDS: dict[str, type[SurrogateModel]] = {"ensemble": EnsembleModel, "lambda": LambdaModel}


def default_model_path() -> Path:
    """The shipped model, ``dipenv/data/`` :data:`DEFAULT_MODEL`."""
    return Path(__file__).resolve().parent.parent / "data" / DEFAULT_MODEL


@lru_cache(maxsize=8)
def _read(path: str, mtime: float) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: np.array(data[k]) for k in data.files if k != "metadata"}
        metadata = json.loads(str(data["metadata"]))
    return arrays, metadata


def load_model(path: str | Path | None = None) -> SurrogateModel:
    """The model stored at ``path`` (default: the shipped one); ``ValueError`` for an unknown kind."""
    resolved = Path(path) if path is not None else default_model_path()
    arrays, metadata = _read(str(resolved.resolve()), resolved.stat().st_mtime)
    kind = metadata.get("kind")
    if kind not in KINDS:
        raise ValueError(f"{resolved}: unknown surrogate model kind {kind!r} (known: {', '.join(KINDS)})")
    return KINDS[kind]({k: v.copy() for k, v in arrays.items()}, metadata)
