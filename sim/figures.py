"""Plots of a run (matplotlib, non-interactive backend)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.observables.stress import rheology
from sim.simulation import StepRecords


def plot_rheology(records: StepRecords, path: Path, transient: float, title: str = "") -> None:
    """eta_r, N1 and N2 (units eta gammadot) against strain, with the discarded transient shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    eta, n1, n2 = rheology(records.total_stress)
    fig, axes = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
    for ax, values, label in zip(
        axes, (eta, n1, n2), (r"$\eta_r$", r"$N_1/\eta\dot\gamma$", r"$N_2/\eta\dot\gamma$"), strict=True
    ):
        ax.plot(records.strain, values, lw=0.6)
        mask = records.strain >= transient
        if np.any(mask):
            ax.axhline(values[mask].mean(), color="k", ls="--", lw=0.8)
        ax.axvspan(0.0, transient, color="0.9")
        ax.set_ylabel(label)
    axes[-1].set_xlabel(r"strain $\dot\gamma t$")
    if title:
        axes[0].set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
