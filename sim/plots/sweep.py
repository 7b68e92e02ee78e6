"""Figures of a sweep (``python -m sim figures DIR``): the paper's rheology, microstructure, dynamics.

Reads every ``DIR/<point>/result.json`` (written by :func:`sim.runs.run.run_simulation`, e.g. through
``python -m sim sweep``), groups the points that differ only in their seed and draws, into
``DIR/figures`` (Matplotlib, Agg backend):

* ``viscosity_vs_phi.png``: ``eta_r`` against ``phi``, one curve per Mason number, with Maron–Pierce
  ``(1 - phi/0.63)^-2``;
* ``viscosity_vs_mason.png``: ``eta_r`` against ``Mn``, one curve per ``phi``; ``Mn = inf`` is drawn at the
  right edge and labelled "no field";
* ``normal_stress_vs_mason.png``: ``N1`` and ``N2`` against ``Mn`` normalised by the pure-shear
  (``Mn = inf``) values of the same ``phi``;
* ``velocity_ratio_vs_mason.png``: ``U_rms^DIP / U_rms^shear`` against ``Mn`` with the crossover ``Mn_c``
  (where the ratio crosses 1, :func:`crossover_mason`) marked and listed in the legend;
* ``pair_distribution.png``: ``g(x, y)``, the pair distribution projected on the shear plane, one panel
  per (``phi``, ``Mn``), from each point's ``pair_distribution.npz`` (``x_edges``, ``y_edges``, ``g_xy``
  indexed ``[x bin, y bin]``, ``samples``; seeds averaged with ``samples`` as weights);
* ``diffusivity.png``: ``D_yy / (gammadot a^2)`` against ``phi`` and against ``Mn`` (``result.json`` key
  ``diffusivity_yy``);
* ``summary.csv``: every plotted number, one row per (``phi``, ``Mn``), and the layer order of
  :mod:`sim.observables.layering` (``layer_order``, ``layer_spacing``, ``layer_onset_strain``: means over the
  seeds that have them; NaN for older folders, and the onset NaN where no seed layered).

Error bars are one standard error: over seeds (sample standard deviation / sqrt(n)) where a point has more
than one seed, else the run's own block-average standard error (NaN where the run has none). A figure
whose data are absent (older sweep folders have no ``pair_distribution.npz`` and no diffusivities) is
skipped with a note. Points that differ in something other than ``phi``, ``Mn`` and the seed (``N``,
mechanism, near field, ...) form separate series, drawn into separate files named after what differs
(``viscosity_vs_phi_N64.png``).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim.runs.io import read_json, save_figure, write_text_atomically

MARON_PIERCE_PHI_MAX = 0.63
"""Maximum packing fraction of the Maron–Pierce curve ``(1 - phi/phi_m)^-2`` drawn for reference."""

SERIES_FIELDS = ("n_particles", "mechanism", "near_field", "shear_rate", "field_direction")
"""``result.json`` keys (besides ``volume_fraction``, ``mason_number``, ``seed``) that separate series."""

QUANTITIES = {
    "eta_r": ("relative_viscosity", "relative_viscosity_stderr"),
    "n1": ("n1", "n1_stderr"),
    "n2": ("n2", "n2_stderr"),
    "u_rms_ratio": (None, None),
    "diffusivity_yy": ("diffusivity_yy", "diffusivity_yy_stderr"),
    "diffusivity_zz": ("diffusivity_zz", "diffusivity_zz_stderr"),
    "particle_pressure": ("particle_pressure", "particle_pressure_stderr"),
    "layer_order": ("layer_order", "layer_order_stderr"),
    "layer_spacing": ("layer_spacing", None),
    "layer_onset_strain": ("layer_onset_strain", None),
}
"""Summary quantity -> (``result.json`` key of the value, of its standard error)."""

PNG_DPI = 120
"""Resolution of the figures."""


def _nan() -> float:
    return math.nan


@dataclass
class Group:
    """The runs of one (series, ``phi``, ``Mn``) that differ only in their seed.

    Attributes:
        volume_fraction: phi.
        mason_number: Mn (``inf``: no field).
        folders: each seed's run folder.
        seeds: the seeds.
        results: each seed's ``result.json``.
        stats: quantity -> (mean, standard error), filled by :func:`summarise_group`.
    """

    volume_fraction: float
    mason_number: float
    folders: list[Path] = field(default_factory=list)
    seeds: list[int] = field(default_factory=list)
    results: list[dict[str, Any]] = field(default_factory=list)
    stats: dict[str, tuple[float, float]] = field(default_factory=dict)


def seed_mean(values: Sequence[float], stderrs: Sequence[float]) -> tuple[float, float]:
    """Mean and standard error over seeds.

    Non-finite values (a quantity a run does not have) are left out. With more than one value: the mean
    and ``std(ddof=1) / sqrt(n)``; with one: that value and its own standard error (``stderrs``, NaN
    if unknown); with none: NaN, NaN.
    """
    kept = [(v, s) for v, s in zip(values, stderrs, strict=True) if math.isfinite(v)]
    if not kept:
        return math.nan, math.nan
    if len(kept) == 1:
        return kept[0]
    array = np.array([v for v, _ in kept])
    return float(array.mean()), float(array.std(ddof=1) / math.sqrt(array.size))


def _value(result: dict[str, Any], key: str | None) -> float:
    value = result.get(key) if key is not None else None
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else math.nan


def velocity_ratio(result: dict[str, Any]) -> float:
    """``U_rms^DIP / U_rms^shear`` of one run; NaN without a field (the DIP part is then 0) or data."""
    dip, shear = _value(result, "u_rms_dip"), _value(result, "u_rms_shear")
    return dip / shear if dip > 0 and shear > 0 else math.nan


def summarise_group(group: Group) -> None:
    """Fill ``group.stats`` with every quantity of :data:`QUANTITIES` (:func:`seed_mean`)."""
    for name, (key, error_key) in QUANTITIES.items():
        if name == "u_rms_ratio":
            values = [velocity_ratio(r) for r in group.results]
            errors = [math.nan] * len(values)
        else:
            values = [_value(r, key) for r in group.results]
            errors = [_value(r, error_key) for r in group.results]
        group.stats[name] = seed_mean(values, errors)


def ratio_with_error(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
    """``a / b`` and its standard error from independent errors of ``a`` and ``b`` (NaN if ``b = 0``)."""
    (va, sa), (vb, sb) = a, b
    if vb == 0 or not math.isfinite(vb):
        return math.nan, math.nan
    ratio = va / vb
    if va == 0:
        return ratio, abs(sa / vb)
    return ratio, abs(ratio) * math.sqrt((sa / va) ** 2 + (sb / vb) ** 2)


def crossover_mason(mason_numbers: Sequence[float], ratios: Sequence[float]) -> float:
    """The Mason number where ``U_rms^DIP / U_rms^shear`` first crosses 1 (going up in ``Mn``).

    Between the two finite Mason numbers ``Mn_i < Mn_j`` whose ratios bracket 1, ``log(ratio)`` is
    interpolated linearly in ``log(Mn)`` (the straight segment of the log-log plot), so
    ``log Mn_c = log Mn_i + log(r_i) / (log r_i - log r_j) (log Mn_j - log Mn_i)``; exact for a power law
    ``r = (Mn / Mn_c)^-p``. Points with a non-positive or non-finite ratio, and ``Mn = inf``, are ignored.

    Returns:
        ``Mn_c``, or NaN if the ratio does not cross 1 within the sampled Mason numbers.
    """
    pairs = sorted(
        (m, r)
        for m, r in zip(mason_numbers, ratios, strict=True)
        if math.isfinite(m) and m > 0 and math.isfinite(r) and r > 0
    )
    for (m0, r0), (m1, r1) in zip(pairs, pairs[1:], strict=False):
        if r0 == 1.0:
            return m0
        if (r0 - 1.0) * (r1 - 1.0) < 0.0:
            log_r0, log_r1 = math.log(r0), math.log(r1)
            t = log_r0 / (log_r0 - log_r1)
            return math.exp(math.log(m0) + t * (math.log(m1) - math.log(m0)))
    if pairs and pairs[-1][1] == 1.0:
        return pairs[-1][0]
    return math.nan


@dataclass
class Series:
    """Groups that share everything but ``phi``, ``Mn`` and the seed; ``label`` tells series apart."""

    key: tuple[Any, ...]
    label: str
    groups: dict[tuple[float, float], Group] = field(default_factory=dict)

    @property
    def phis(self) -> list[float]:
        return sorted({phi for phi, _ in self.groups})

    @property
    def masons(self) -> list[float]:
        return sorted({mn for _, mn in self.groups})

    def crossovers(self) -> dict[float, float]:
        """``Mn_c`` per ``phi`` (:func:`crossover_mason` of the seed-averaged ratios)."""
        out = {}
        for phi in self.phis:
            groups = [g for (p, _), g in self.groups.items() if p == phi]
            out[phi] = crossover_mason(
                [g.mason_number for g in groups], [g.stats["u_rms_ratio"][0] for g in groups]
            )
        return out

    def normalised(self, name: str, phi: float, mason: float) -> tuple[float, float]:
        """``name`` (``n1``, ``n2``) at (phi, Mn) over its pure-shear value at the same phi."""
        pure = self.groups.get((phi, math.inf))
        group = self.groups.get((phi, mason))
        if pure is None or group is None:
            return math.nan, math.nan
        return ratio_with_error(group.stats[name], pure.stats[name])


def _series_key(result: dict[str, Any]) -> tuple[Any, ...]:
    """The values of :data:`SERIES_FIELDS`; ``near_field`` is None for a pure-shear run (no field: the
    near-field model plays no part, and ``result.json`` says ``none`` there)."""
    values = []
    for name in SERIES_FIELDS:
        value = result.get(name)
        if name == "near_field" and math.isinf(float(result["mason_number"])):
            value = None
        values.append(tuple(value) if isinstance(value, list) else value)
    return tuple(values)


def _series_keys(key: tuple[Any, ...], finite_keys: set[tuple[Any, ...]]) -> list[tuple[Any, ...]]:
    """The series a run belongs to: its own, or for a pure-shear run (``near_field`` None) every series
    with a field that agrees in all else (pure shear is the reference of each near-field model)."""
    index = SERIES_FIELDS.index("near_field")
    if key[index] is not None:
        return [key]
    rest = key[:index] + key[index + 1 :]
    matches = sorted((k for k in finite_keys if k[:index] + k[index + 1 :] == rest), key=repr)
    return matches or [key]


def _series_label(key: tuple[Any, ...], keys: Sequence[tuple[Any, ...]]) -> str:
    """What tells this series apart from the others (``N64_dep``); empty if there is one series."""
    parts = []
    for index, name in enumerate(SERIES_FIELDS):
        if len({k[index] for k in keys}) < 2:
            continue
        value = key[index]
        if name == "n_particles":
            parts.append(f"N{value}")
        elif name == "shear_rate":
            parts.append("quiescent" if value == 0 else "sheared")
        elif name == "field_direction":
            parts.append("e" + ",".join(f"{c:.3g}" for c in value) if value else "e?")
        elif name == "near_field":
            parts += [f"near-{value}"] if value is not None else []
        else:
            parts.append(str(value))
    return "_".join(parts)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def read_result(path: Path) -> dict[str, Any]:
    """A point's ``result.json``, checked for what the figures read; ``ValueError`` naming the file when
    it cannot be read, is not JSON (truncated, binary) or lacks the fields (another file's shape).

    Required: ``volume_fraction`` (a number), ``mason_number`` (a number > 0 or ``inf``); optional but
    typed: ``seed`` (an integer), the :data:`SERIES_FIELDS` (``field_direction`` three numbers, the others
    a number or a string). The quantities of :data:`QUANTITIES` may be absent or non-numeric (NaN then).
    """
    redo = "remove that point's folder, or rerun the sweep to redo it"
    try:
        result = read_json(path)
    except OSError as exc:
        raise ValueError(f"{path}: cannot be read: {exc.strerror or exc}") from None
    except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError
        raise ValueError(f"{path}: not a valid result.json ({type(exc).__name__}: {exc}); {redo}") from None
    if not isinstance(result, dict):
        kind = type(result).__name__
        raise ValueError(f"{path}: not a run's result (a JSON object expected, got {kind}); {redo}")
    problems = []
    phi: Any = result.get("volume_fraction")
    mason: Any = result.get("mason_number")
    if not (_is_number(phi) and 0.0 < phi < 1.0):
        problems.append(f"volume_fraction must be a number in (0, 1), got {phi!r}")
    if not (_is_number(mason) and mason > 0.0):
        problems.append(f"mason_number must be a number > 0 or 'inf', got {mason!r}")
    seed = result.get("seed", -1)
    if isinstance(seed, bool) or not isinstance(seed, int):
        problems.append(f"seed must be an integer, got {seed!r}")
    for name in SERIES_FIELDS:
        value = result.get(name)
        if name == "field_direction":
            if value is not None and not (
                isinstance(value, list) and len(value) == 3 and all(_is_number(c) for c in value)
            ):
                problems.append(f"field_direction must be three numbers, got {value!r}")
        elif value is not None and not (_is_number(value) or isinstance(value, str)):
            problems.append(f"{name} must be a number or a word, got {value!r}")
    if problems:
        raise ValueError(f"{path}: not a run's result: {'; '.join(problems)}; {redo}")
    return result


def load_sweep(directory: str | Path) -> list[Series]:
    """Every run below ``directory`` with a ``result.json``, grouped into series and seed groups.

    Raises:
        FileNotFoundError: ``directory`` is not a folder; ValueError: it holds no ``result.json``, or one
        that is corrupt or of another shape (:func:`read_result`).
    """
    root = Path(directory)
    if not root.is_dir():
        raise FileNotFoundError(f"DIR {root} is not a folder (give the --out of python -m sim sweep)")
    files = sorted(root.glob("*/result.json"))
    if not files:
        raise ValueError(f"DIR {root}: no <point>/result.json in it (has the sweep finished a point yet?)")
    loaded = [(path, read_result(path)) for path in files]
    finite_keys = {_series_key(r) for _, r in loaded if math.isfinite(float(r["mason_number"]))}
    by_key: dict[tuple[Any, ...], Series] = {}
    for path, result in loaded:
        for key in _series_keys(_series_key(result), finite_keys):
            series = by_key.setdefault(key, Series(key=key, label=""))
            phi, mason = float(result["volume_fraction"]), float(result["mason_number"])
            group = series.groups.setdefault((phi, mason), Group(volume_fraction=phi, mason_number=mason))
            group.folders.append(path.parent)
            group.seeds.append(int(result.get("seed", -1)))
            group.results.append(result)
    keys = list(by_key)
    for series in by_key.values():
        series.label = _series_label(series.key, keys)
        for group in series.groups.values():
            summarise_group(group)
    return [by_key[k] for k in keys]


# --- plotting -----------------------------------------------------------------------------------------


def _figure(width: float, height: float, columns: int = 1, rows: int = 1) -> tuple[Any, Any]:
    """A Matplotlib figure on the Agg canvas (no pyplot state) and its axes array."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, columns, squeeze=False)
    return fig, axes


def _colours(count: int) -> list[Any]:
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    return [cmap(0.85 * i / max(count - 1, 1)) for i in range(count)]


def _mason_label(mason: float) -> str:
    return "no field (Mn = ∞)" if math.isinf(mason) else f"Mn = {mason:g}"


MASON_AXIS = r"Mason number $Mn = \eta\dot\gamma/(\varepsilon E_0^2)$"


def _no_field_position(masons: Sequence[float]) -> float:
    """Where ``Mn = inf`` sits on a log axis: one decade right of the largest finite ``Mn`` (or 1)."""
    finite = [m for m in masons if math.isfinite(m)]
    return 10.0 * max(finite) if finite else 1.0


def _mason_axis(ax: Any, masons: Sequence[float]) -> float:
    """Log x axis of ``Mn`` with ``inf`` at the right edge (tick "no field"); returns its position."""
    ax.set_xscale("log")
    ax.set_xlabel(MASON_AXIS)
    x_inf = _no_field_position(masons)
    finite = [m for m in masons if math.isfinite(m)]
    if any(math.isinf(m) for m in masons):
        if finite:
            ax.axvline(math.sqrt(max(finite) * x_inf), color="0.7", lw=0.8, ls=":")
        ticks = sorted(set(finite)) + [x_inf]
        ax.set_xticks(ticks, [f"{m:g}" for m in sorted(set(finite))] + ["no field"])
        ax.minorticks_off()
    return x_inf


def _errorbar_mason(
    ax: Any, masons: list[float], values: list[float], errors: list[float], **style: Any
) -> None:
    """One curve against ``Mn``: a line through the finite ``Mn``, an open marker at "no field"."""
    x_inf = _no_field_position(masons)
    finite = [i for i, m in enumerate(masons) if math.isfinite(m)]
    line = ax.errorbar(
        [masons[i] for i in finite],
        [values[i] for i in finite],
        yerr=[_bar(errors[i]) for i in finite],
        fmt="o-",
        capsize=3,
        **style,
    )
    colour = line[0].get_color()
    for i, m in enumerate(masons):
        if math.isinf(m):
            ax.errorbar(
                [x_inf], [values[i]], yerr=[_bar(errors[i])], fmt="s", mfc="white", color=colour, capsize=3
            )


def _bar(error: float) -> float:
    """An error bar length Matplotlib accepts (no bar for an unknown error)."""
    return error if math.isfinite(error) else 0.0


def _save(fig: Any, path: Path, written: list[Path]) -> None:
    save_figure(fig, path, dpi=PNG_DPI)
    written.append(path)


def _name(base: str, series: Series) -> str:
    return f"{base}_{series.label}.png" if series.label else f"{base}.png"


def _title(fig: Any, series: Series) -> None:
    if series.label:
        fig.suptitle(series.label.replace("_", ", "))


def _plot_against_phi(ax: Any, series: Series, key: str) -> None:
    """Group statistic ``key`` (mean, standard error) against ``phi``, one curve per ``Mn`` of ``series``."""
    masons = series.masons
    for mason, colour in zip(masons, _colours(len(masons)), strict=True):
        groups = [series.groups[(p, mason)] for p in series.phis if (p, mason) in series.groups]
        ax.errorbar(
            [g.volume_fraction for g in groups],
            [g.stats[key][0] for g in groups],
            yerr=[_bar(g.stats[key][1]) for g in groups],
            fmt="o-" if math.isfinite(mason) else "s--",
            color=colour,
            capsize=3,
            label=_mason_label(mason),
        )


def _plot_against_mason(ax: Any, series: Series, key: str) -> None:
    """Group statistic ``key`` against ``Mn`` (axis of :func:`_mason_axis`), one curve per ``phi``."""
    _mason_axis(ax, series.masons)
    for phi, colour in zip(series.phis, _colours(len(series.phis)), strict=True):
        groups = [series.groups[(phi, m)] for m in series.masons if (phi, m) in series.groups]
        _errorbar_mason(
            ax,
            [g.mason_number for g in groups],
            [g.stats[key][0] for g in groups],
            [g.stats[key][1] for g in groups],
            color=colour,
            label=rf"$\phi$ = {phi:g}",
        )


def plot_maron_pierce(ax: Any, phi_end: float, phi_max: float, fmt: str, label: str) -> None:
    """The Maron–Pierce curve ``(1 - phi/phi_max)^-2`` on ``0 <= phi <= phi_end`` (200 points, thin line)."""
    curve = np.linspace(0.0, phi_end, 200)
    ax.plot(curve, (1.0 - curve / phi_max) ** -2, fmt, lw=1, label=label)


def plot_viscosity_vs_phi(series: Series, path: Path, written: list[Path]) -> None:
    """``eta_r(phi)`` per ``Mn`` with Maron–Pierce."""
    fig, axes = _figure(6.0, 4.4)
    ax = axes[0, 0]
    _plot_against_phi(ax, series, "eta_r")
    phi_max = max(series.phis)
    plot_maron_pierce(
        ax,
        min(phi_max + 0.02, 0.6),
        MARON_PIERCE_PHI_MAX,
        "k:",
        rf"Maron–Pierce $(1-\phi/{MARON_PIERCE_PHI_MAX})^{{-2}}$",
    )
    ax.set_xlabel(r"volume fraction $\phi$")
    ax.set_ylabel(r"relative viscosity $\eta_r = \Sigma_{xy}/(\eta\dot\gamma)$")
    ax.legend(fontsize="small")
    _title(fig, series)
    _save(fig, path, written)


def plot_viscosity_vs_mason(series: Series, path: Path, written: list[Path]) -> None:
    """``eta_r(Mn)`` per ``phi``; ``Mn = inf`` at the right edge."""
    fig, axes = _figure(6.0, 4.4)
    ax = axes[0, 0]
    _plot_against_mason(ax, series, "eta_r")
    ax.set_ylabel(r"relative viscosity $\eta_r = \Sigma_{xy}/(\eta\dot\gamma)$")
    ax.legend(fontsize="small")
    _title(fig, series)
    _save(fig, path, written)


def plot_normal_stresses(series: Series, path: Path, written: list[Path], log: Callable[[str], None]) -> None:
    """``N1/N1(inf)`` and ``N2/N2(inf)`` against ``Mn`` per ``phi``."""
    phis = [p for p in series.phis if (p, math.inf) in series.groups]
    for phi in series.phis:
        if phi not in phis:
            log(f"note: phi = {phi:g} left out of {path.name}: no Mn = inf point to normalise N1, N2 by")
    if not phis:
        log(f"note: {path.name} skipped: no pure-shear (Mn = inf) point to normalise N1 and N2 by")
        return
    fig, axes = _figure(10.0, 4.2, columns=2)
    for ax, name, label in (
        (axes[0, 0], "n1", r"$N_1 / N_1(Mn = \infty)$"),
        (axes[0, 1], "n2", r"$N_2 / N_2(Mn = \infty)$"),
    ):
        _mason_axis(ax, series.masons)
        for phi, colour in zip(phis, _colours(len(phis)), strict=True):
            masons = [m for m in series.masons if (phi, m) in series.groups]
            pairs = [series.normalised(name, phi, m) for m in masons]
            _errorbar_mason(
                ax,
                masons,
                [v for v, _ in pairs],
                [e for _, e in pairs],
                color=colour,
                label=rf"$\phi$ = {phi:g}",
            )
        ax.axhline(0.0, color="k", lw=0.5)
        ax.axhline(1.0, color="0.6", lw=0.5, ls="--")
        ax.set_ylabel(label + " (pure-shear value of the same $\\phi$)")
        ax.legend(fontsize="small")
    _title(fig, series)
    _save(fig, path, written)


def plot_velocity_ratio(series: Series, path: Path, written: list[Path], log: Callable[[str], None]) -> None:
    """``U_rms^DIP / U_rms^shear`` against ``Mn`` (log-log) with ``Mn_c`` marked per ``phi``."""
    crossovers = series.crossovers()
    curves = []
    for phi in series.phis:
        groups = [
            series.groups[(phi, m)]
            for m in series.masons
            if (phi, m) in series.groups
            and math.isfinite(m)
            and math.isfinite(series.groups[(phi, m)].stats["u_rms_ratio"][0])
        ]
        if groups:
            curves.append((phi, groups))
    if not curves:
        log(f"note: {path.name} skipped: no point with a field (finite Mn) and U_rms^DIP, U_rms^shear")
        return
    fig, axes = _figure(6.0, 4.4)
    ax = axes[0, 0]
    for (phi, groups), colour in zip(curves, _colours(len(curves)), strict=True):
        mn_c = crossovers[phi]
        crossing = f", $Mn_c$ = {mn_c:.3g}" if math.isfinite(mn_c) else ", no crossing"
        ax.errorbar(
            [g.mason_number for g in groups],
            [g.stats["u_rms_ratio"][0] for g in groups],
            yerr=[_bar(g.stats["u_rms_ratio"][1]) for g in groups],
            fmt="o-",
            color=colour,
            capsize=3,
            label=rf"$\phi$ = {phi:g}{crossing}",
        )
        if math.isfinite(mn_c):
            ax.axvline(mn_c, color=colour, lw=0.8, ls="--")
            ax.plot([mn_c], [1.0], marker="x", color=colour, ms=9)
        log(f"phi = {phi:g}{' (' + series.label + ')' if series.label else ''}: Mn_c = {mn_c:.4g}")
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(MASON_AXIS)
    ax.set_ylabel(r"$U_{rms}^{DIP} / U_{rms}^{shear}$ (RMS particle velocities)")
    ax.legend(fontsize="small")
    _title(fig, series)
    _save(fig, path, written)


def mean_pair_distribution(group: Group) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Seed-averaged ``(x_edges, y_edges, g[x, y])`` of a group, weighted by ``samples``; None if absent."""
    total, weight, edges = None, 0.0, None
    for folder in group.folders:
        path = folder / "pair_distribution.npz"
        if not path.exists():
            continue
        with np.load(path) as data:
            x_edges, y_edges, g = data["x_edges"], data["y_edges"], np.asarray(data["g_xy"], dtype=float)
            samples = float(np.sum(data["samples"])) if "samples" in data else 1.0
        if g.shape != (x_edges.size - 1, y_edges.size - 1):
            continue
        if edges is not None and not (
            np.array_equal(edges[0], x_edges) and np.array_equal(edges[1], y_edges)
        ):
            continue
        edges = (x_edges, y_edges)
        total = g * samples if total is None else total + g * samples
        weight += samples
    if total is None or edges is None or weight <= 0:
        return None
    return edges[0], edges[1], total / weight


def plot_pair_distributions(
    series: Series, path: Path, written: list[Path], log: Callable[[str], None]
) -> None:
    """``g(x, y)`` on the shear plane, rows ``phi``, columns ``Mn``, one colour scale."""
    data = {key: mean_pair_distribution(g) for key, g in series.groups.items()}
    if not any(v is not None for v in data.values()):
        log(f"note: {path.name} skipped: no pair_distribution.npz in the run folders")
        return
    phis, masons = series.phis, series.masons
    fig, axes = _figure(2.6 * len(masons) + 1.0, 2.5 * len(phis) + 0.4, columns=len(masons), rows=len(phis))
    top = max(float(np.nanpercentile(v[2], 99.5)) for v in data.values() if v is not None)
    image = None
    for row, phi in enumerate(phis):
        for column, mason in enumerate(masons):
            ax = axes[row, column]
            values = data.get((phi, mason))
            ax.set_title(rf"$\phi$ = {phi:g}, {_mason_label(mason)}", fontsize="small")
            if values is None:
                ax.text(0.5, 0.5, "no data", ha="center", va="center", transform=ax.transAxes)
                ax.set_xticks([])
                ax.set_yticks([])
                continue
            x_edges, y_edges, g = values
            image = ax.pcolormesh(x_edges, y_edges, g.T, cmap="magma", vmin=0.0, vmax=max(top, 1e-12))
            ax.set_aspect("equal")
            if row == len(phis) - 1:
                ax.set_xlabel(r"$x/a$ (flow)")
            if column == 0:
                ax.set_ylabel(r"$y/a$ (gradient, field)")
    if image is not None:
        fig.colorbar(image, ax=axes, label=r"$g(x, y)$ (1 = uncorrelated)", shrink=0.8)
    _title(fig, series)
    _save(fig, path, written)


def plot_diffusivity(series: Series, path: Path, written: list[Path], log: Callable[[str], None]) -> None:
    """``D_yy`` against ``phi`` (per ``Mn``) and against ``Mn`` (per ``phi``)."""
    if not any(math.isfinite(g.stats["diffusivity_yy"][0]) for g in series.groups.values()):
        log(
            f"note: {path.name} skipped: no finite diffusivity_yy in the runs' result.json (older sweeps "
            "have none; runs too short for the MSD fit give NaN, see their diffusivity_note)"
        )
        return
    fig, axes = _figure(10.0, 4.2, columns=2)
    label = r"diffusivity $D_{yy}/(\dot\gamma a^2)$"
    ax = axes[0, 0]
    _plot_against_phi(ax, series, "diffusivity_yy")
    ax.set_xlabel(r"volume fraction $\phi$")
    ax.set_ylabel(label)
    ax.legend(fontsize="small")
    ax = axes[0, 1]
    _plot_against_mason(ax, series, "diffusivity_yy")
    ax.set_ylabel(label)
    ax.legend(fontsize="small")
    _title(fig, series)
    _save(fig, path, written)


SUMMARY_COLUMNS = (
    "series",
    "n_particles",
    "mechanism",
    "near_field",
    "volume_fraction",
    "mason_number",
    "n_seeds",
    "seeds",
    "eta_r",
    "eta_r_stderr",
    "maron_pierce",
    "n1",
    "n1_stderr",
    "n2",
    "n2_stderr",
    "n1_over_pure_shear",
    "n1_over_pure_shear_stderr",
    "n2_over_pure_shear",
    "n2_over_pure_shear_stderr",
    "u_rms_ratio",
    "u_rms_ratio_stderr",
    "mason_crossover",
    "diffusivity_yy",
    "diffusivity_yy_stderr",
    "diffusivity_zz",
    "diffusivity_zz_stderr",
    "particle_pressure",
    "particle_pressure_stderr",
    "layer_order",
    "layer_order_stderr",
    "layer_spacing",
    "layer_spacing_stderr",
    "layer_onset_strain",
    "layer_onset_strain_stderr",
)
"""Columns of ``summary.csv`` (``mason_crossover`` is the ``Mn_c`` of the row's ``phi``; standard errors
as in the figures; ``inf``/``nan`` written as such)."""


def summary_rows(series_list: Sequence[Series]) -> list[dict[str, Any]]:
    """One row per (series, ``phi``, ``Mn``) with :data:`SUMMARY_COLUMNS`."""
    rows = []
    for series in series_list:
        crossovers = series.crossovers()
        for (phi, mason), group in sorted(series.groups.items()):
            first = group.results[0]
            row: dict[str, Any] = {
                "series": series.label,
                "n_particles": first.get("n_particles"),
                "mechanism": first.get("mechanism"),
                "near_field": first.get("near_field"),
                "volume_fraction": phi,
                "mason_number": mason,
                "n_seeds": len(group.results),
                "seeds": " ".join(str(s) for s in sorted(group.seeds)),
                "maron_pierce": (1.0 - phi / MARON_PIERCE_PHI_MAX) ** -2,
                "mason_crossover": crossovers[phi],
            }
            for name in QUANTITIES:
                row[name], row[f"{name}_stderr"] = group.stats[name]
            for name in ("n1", "n2"):
                row[f"{name}_over_pure_shear"], row[f"{name}_over_pure_shear_stderr"] = series.normalised(
                    name, phi, mason
                )
            rows.append(row)
    return rows


def write_summary(rows: Sequence[dict[str, Any]], path: Path) -> None:
    """``summary.csv``: floats in full precision (``repr``), ``inf`` and ``nan`` as words."""
    handle = io.StringIO(newline="")
    writer = csv.DictWriter(handle, fieldnames=SUMMARY_COLUMNS)
    writer.writeheader()
    for row in rows:
        writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in row.items()})
    write_text_atomically(Path(path), handle.getvalue())


def make_figures(
    directory: str | Path, out: str | Path | None = None, log: Callable[[str], None] | None = print
) -> list[Path]:
    """Draw every figure of the sweep in ``directory`` into ``out`` (default ``directory/figures``).

    Args:
        directory: a sweep folder (``python -m sim sweep --out``).
        out: folder of the figures (created).
        log: called with notes (skipped figures, the crossover Mason numbers); None for silence.

    Returns:
        The files written (PNGs and ``summary.csv``).

    Raises:
        FileNotFoundError: ``directory`` is not a folder; ValueError: it holds no ``result.json``.
    """
    say = log or (lambda line: None)
    series_list = load_sweep(directory)
    target = Path(out) if out is not None else Path(directory) / "figures"
    target.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for series in series_list:
        plot_viscosity_vs_phi(series, target / _name("viscosity_vs_phi", series), written)
        plot_viscosity_vs_mason(series, target / _name("viscosity_vs_mason", series), written)
        plot_normal_stresses(series, target / _name("normal_stress_vs_mason", series), written, say)
        plot_velocity_ratio(series, target / _name("velocity_ratio_vs_mason", series), written, say)
        plot_pair_distributions(series, target / _name("pair_distribution", series), written, say)
        plot_diffusivity(series, target / _name("diffusivity", series), written, say)
    summary = target / "summary.csv"
    write_summary(summary_rows(series_list), summary)
    written.append(summary)
    return written
