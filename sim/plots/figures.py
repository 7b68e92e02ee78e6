"""Plots of a run (matplotlib, non-interactive backend)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.observables.layering import (
    AXIS_NAMES,
    LAYERED_MIN_STRUCTURE_FACTOR,
    ONSET_FRACTION,
    LayerOrderSeries,
    LayerSummary,
)
from sim.plots.sweep import plot_maron_pierce
from sim.runs.io import save_figure
from sim.simulation import StepRecords


def plot_rheology(records: StepRecords, path: Path, transient: float, title: str = "") -> None:
    """eta_r, N1 and N2 (units eta gammadot_ref) against time, with the discarded transient shaded.

    A legend above the panels explains the marks: the per-step values (thin line), the transient that
    the averages discard (grey band, time 0 to ``transient``, a clock time) and the mean over the rest
    (dashed line). Time is in ``1/gammadot_ref``: at the reference rate it is the strain.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    eta, n1, n2 = records.rheology()
    fig, axes = plt.subplots(3, 1, figsize=(7, 7.4), sharex=True, layout="constrained")
    for ax, values, label in zip(
        axes, (eta, n1, n2), (r"$\eta_r$", r"$N_1/\eta\dot\gamma$", r"$N_2/\eta\dot\gamma$"), strict=True
    ):
        ax.plot(records.time, values, lw=0.6, label="per step")
        ax.axvspan(0.0, transient, color="0.9", label=f"transient (time < {transient:g}), discarded")
        mask = records.time >= transient
        if np.any(mask):
            ax.axhline(values[mask].mean(), color="k", ls="--", lw=0.8, label="mean after the transient")
        ax.set_ylabel(label)
    axes[-1].set_xlabel(r"time $\dot\gamma_\mathrm{ref} t$ (the strain at the reference rate)")
    if title:
        axes[0].set_title(title)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper center", ncol=3, fontsize="small", frameon=False)
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def plot_layering(series: LayerOrderSeries, summary: LayerSummary, transient: float, path: Path) -> None:
    """Layer order ``psi = S_peak / N`` against strain (against time when the strain stays 0: quiescent).

    Marks: the samples (line with dots), the transient (grey band, clock 0 to ``transient``), the plateau
    (mean after the transient, dashed), the onset threshold ``ONSET_FRACTION`` x plateau and the onset
    (dotted, only when the run has layered) and the ideal-gas level ``1/N`` (thin grey). See
    :mod:`sim.observables.layering`.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = series.table()
    time, strain, psi = table[:, 0], table[:, 1], table[:, 2]
    use_strain = bool(strain.size) and bool(np.any(strain != 0.0))
    x = strain if use_strain else time

    def to_x(clock: float) -> float:
        return float(np.interp(clock, time, strain)) if use_strain else clock

    fig, ax = plt.subplots(figsize=(7, 3.8), layout="constrained")
    if x.size:
        ax.axvspan(float(x[0]), to_x(transient), color="0.9", label="transient, not averaged")
    ax.plot(x, psi, "-", lw=0.8, marker=".", ms=3, label=r"$\psi = S_\mathrm{peak}/N$")
    ax.axhline(1.0 / series.n_particles, color="0.5", lw=0.6, label="ideal gas, one $k$: $1/N$")
    if np.isfinite(summary.order):
        ax.axhline(summary.order, color="k", ls="--", lw=0.8, label=f"plateau {summary.order:.3g}")
    if np.isfinite(summary.onset_time):
        ax.axhline(
            ONSET_FRACTION * summary.order, color="C3", ls=":", lw=0.8, label=f"{ONSET_FRACTION:g} x plateau"
        )
        onset = summary.onset_strain if use_strain else summary.onset_time
        ax.axvline(onset, color="C3", ls=":", lw=0.8, label=f"onset at {onset:.3g}")
    ax.set_ylim(0.0, max(1.05 * float(psi.max()) if psi.size else 0.0, 2.0 / series.n_particles))
    ax.set_xlabel(r"strain $\gamma$" if use_strain else "time")
    ax.set_ylabel(r"$\psi$")
    ax.set_title(
        f"layer order along {AXIS_NAMES[series.axis]}, N = {series.n_particles}, "
        f"L = {series.box_length:.3g} a (layered: plateau S >= {LAYERED_MIN_STRUCTURE_FACTOR:g})",
        fontsize="small",
    )
    ax.legend(fontsize="small", frameon=False)
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def plot_viscosity_curve(
    volume_fractions: list[float],
    results: list[dict],
    path: Path,
    maron_pierce_phi_max: float = 0.63,
) -> None:
    """eta_r(phi) with Maron–Pierce ``(1 - phi/phi_m)^-2`` and N1, N2 (phi), one point per run.

    ``results`` are run results (``result.json`` dictionaries: ``relative_viscosity``, ``n1``, ``n2`` and
    their ``*_stderr``); error bars are one standard error.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    phi = np.asarray(volume_fractions)
    fig, (ax_eta, ax_n) = plt.subplots(1, 2, figsize=(10, 4))
    plot_maron_pierce(
        ax_eta,
        max(phi.max(), 0.5) + 0.02,
        maron_pierce_phi_max,
        "k--",
        f"Maron–Pierce, $\\phi_m$ = {maron_pierce_phi_max}",
    )
    ax_eta.errorbar(
        phi,
        [r["relative_viscosity"] for r in results],
        yerr=[r["relative_viscosity_stderr"] for r in results],
        fmt="o",
        label="simulation",
    )
    ax_eta.set_yscale("log")
    ax_eta.set_xlabel(r"$\phi$")
    ax_eta.set_ylabel(r"$\eta_r$")
    ax_eta.legend()
    for key, label in (("n1", r"$N_1$"), ("n2", r"$N_2$")):
        ax_n.errorbar(
            phi, [r[key] for r in results], yerr=[r[f"{key}_stderr"] for r in results], fmt="o-", label=label
        )
    ax_n.axhline(0.0, color="k", lw=0.5)
    ax_n.set_xlabel(r"$\phi$")
    ax_n.set_ylabel(r"normal stress difference / $\eta\dot\gamma$")
    ax_n.legend()
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)
