"""What a run samples besides its step records: g(r), its x–y projection, the displacement for the MSD and
the layer order.

A run samples two observables at the fixed clock times ``t_k = k * sample_interval`` from the end of the
transient on (:class:`RunObservables`): the accumulated non-affine displacement at every ``t_k``, for the
mean-square displacement over all time origins from which the diffusivities ``D_xx``, ``D_yy``, ``D_zz``
are fitted (:mod:`sim.observables.diffusion`), and, at every :data:`PAIR_SAMPLE_STRIDE`-th ``t_k``, the
pair distribution ``g(r)`` and its x–y projection, summed over the sampled configurations
(:mod:`sim.observables.pair_distribution`). A third, the layer order along the field (``psi``,
``S_peak``, ``k_peak``, spacing; :mod:`sim.observables.layering`), is sampled at every ``t_k`` from
``t_0 = 0``, the transient included, so that the strain at which layers form can be read off. The step
loop stops at each ``t_k`` (at the first step that reaches it; stopping never changes the trajectory).
A run started from a given configuration (``run_simulation(..., state=...)``) starts its clock where the
state's is, ``t_0``: its sample times are ``t_k = t_0 + k * sample_interval`` (:attr:`RunObservables.origin`)
and its transient is counted from ``t_0``.
Measured cost of the sampling (shared 2-core VM, phi = 0.45, pure shear, the cheapest steps, default
interval): 0.4% of the run time at N = 64, 1.3% at N = 500, 1.5% at N = 2000 over its first 0.3 strain
(a g sample takes 6–10 ms at N = 500 and 37 ms at N = 2000, an MSD sample 0.35 and 1.8 ms, a layer-order
sample 0.1 ms at N = 500, against 25 steps of 8 and 50 ms). The accumulators travel in the checkpoint and
a resumed run continues them bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim.config import SimulationConfig
from sim.observables.diffusion import (
    DIFFUSIVITY_FIT_START,
    MIN_INDEPENDENT_SEGMENTS,
    MsdAccumulator,
    diffusivity_fit_window,
    fit_diffusivity,
)
from sim.observables.layering import (
    AXIS_NAMES,
    LayerOrderSeries,
    nearest_layer_axis,
    summarise_layering,
)
from sim.observables.microstructure import (
    DEFAULT_CONTACT_GAP,
    DEFAULT_FABRIC_CUTOFF,
    contact_number,
    fabric_tensor,
)
from sim.observables.pair_distribution import PairDistributionAccumulator
from sim.plots.figures import plot_layering
from sim.runs import io
from sim.simulation import Simulation, StepRecords
from sim.stepper import stop_time

DEFAULT_SAMPLE_INTERVAL = 0.05
"""Clock interval between displacement samples (strain; a/U0 when quiescent): 25 steps of the default
``time_step``, fine enough to resolve the ballistic part of the MSD (lags from 0.05) and to give the
diffusive window [1, 5] of a default run 81 lags."""

PAIR_SAMPLE_STRIDE = 4
"""The pair distribution is sampled at every 4th sample time (every 0.2 strain by default): the pair
structure changes little over 0.05 strain, and a g sample costs as much as a few steps (37 ms at N = 2000)."""

MSD_MAX_LAG_TIME = 10.0
"""Largest lag of the accumulated MSD (strain; a/U0 when quiescent): twice the fit window's end in a
default run (30 strains, transient 10: window [1, 5]); the fit of longer runs stops here."""

MSD_MAX_LAGS = 1000
"""At most this many lags (samples) are accumulated, whatever the interval: the MSD's ring buffer holds
``MSD_MAX_LAGS + 1`` displacement arrays (48 MB at N = 2000), so a very fine ``sample_interval`` shortens
the largest lag below :data:`MSD_MAX_LAG_TIME` instead of filling memory."""


def first_sample_index(transient: float, sample_interval: float) -> int:
    """Smallest ``k`` with ``t_k = k * sample_interval`` at or after ``transient`` (1e-9 relative slack)."""
    return max(int(math.ceil(transient / sample_interval - 1e-9)), 0)


@dataclass
class RunObservables:
    """What a run samples at the clock times ``t_k = origin + k * sample_interval``, ``k >= first_index``.

    Attributes:
        sample_interval: ``Delta`` between samples (time units).
        first_index: index of the first sample (the first ``t_k`` at or after the transient).
        next_index: index of the next sample to take.
        pair_distribution: ``g(r)`` and x–y counts of the configurations at ``t_k`` with
            ``k - first_index`` a multiple of :data:`PAIR_SAMPLE_STRIDE`.
        msd: the MSD of the accumulated non-affine displacement over all origins (lags up to
            :data:`MSD_MAX_LAG_TIME`, at most :data:`MSD_MAX_LAGS` samples).
        note: why the samples start elsewhere than at the run's transient (empty when they do not).
        fabric_sum: (3, 3) sum of the fabric tensors ``<n n>`` of the configurations ``g`` is sampled at
            (pairs closer than :data:`~sim.observables.microstructure.DEFAULT_FABRIC_CUTOFF`).
        contact_sum: sum of their contact numbers (gap below
            :data:`~sim.observables.microstructure.DEFAULT_CONTACT_GAP`).
        structure_samples: how many configurations the two sums hold.
        layering: the layer order at ``t_k``, ``k >= 0`` (transient included), along the box axis
            nearest the configured field direction (:func:`~sim.observables.layering.nearest_layer_axis`:
            the field's own axis when it is one; ``y`` in pure shear).
        layer_next_index: index of the next layer-order sample (runs ahead of ``next_index`` during
            the transient, equal to it after).
        layer_note: why the layer order starts later than ``t_0`` (empty when it does not).
        averaging_from_time: clock from which the layer order is averaged (the run's transient; set from
            the configuration, not stored in the checkpoint).
        origin: the clock at which the run started, ``t_0`` (0 for a run from a fresh packing; the state's
            clock for a run from a given configuration); set by the run, not stored in the checkpoint.
    """

    sample_interval: float
    first_index: int
    next_index: int
    pair_distribution: PairDistributionAccumulator
    msd: MsdAccumulator
    note: str = ""
    fabric_sum: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    contact_sum: float = 0.0
    structure_samples: int = 0
    layering: LayerOrderSeries | None = None
    layer_next_index: int = 0
    layer_note: str = ""
    averaging_from_time: float = 0.0
    origin: float = 0.0

    @classmethod
    def fresh(
        cls,
        config: SimulationConfig,
        sample_interval: float,
        first_index: int,
        note: str = "",
        origin: float = 0.0,
    ) -> RunObservables:
        """Empty accumulators whose first sample is ``t_{first_index}`` (layer order: ``t_0``); the run
        started at the clock ``origin``."""
        max_lag = min(max(int(round(MSD_MAX_LAG_TIME / sample_interval)), 1), MSD_MAX_LAGS)
        return cls(
            sample_interval=float(sample_interval),
            first_index=int(first_index),
            next_index=int(first_index),
            pair_distribution=PairDistributionAccumulator.for_box(config.n_particles, config.box_length),
            msd=MsdAccumulator.create(config.n_particles, max_lag),
            note=note,
            layering=cls._fresh_layering(config),
            averaging_from_time=origin + config.transient_time,
            origin=float(origin),
        )

    @staticmethod
    def _fresh_layering(config: SimulationConfig) -> LayerOrderSeries:
        """An empty layer-order series along the box axis nearest ``config.field_direction``."""
        return LayerOrderSeries(
            box_length=config.box_length,
            axis=nearest_layer_axis(config.field_direction),
            n_particles=config.n_particles,
            rows=[],
        )

    @classmethod
    def for_run(
        cls,
        config: SimulationConfig,
        sample_interval: float,
        records: StepRecords | None,
        saved: Mapping[str, np.ndarray] | None,
        names: Mapping[str, str] | None = None,
        origin: float = 0.0,
    ) -> RunObservables:
        """The accumulators of a run that starts (at the clock ``origin``), or resumes, after ``records``.

        A resumed run continues the checkpoint's accumulators when they started at this run's transient
        (bit for bit the uninterrupted run's). When the transient has moved (a run extended on resume with
        the default transient, half of a run shorter than 20) the accumulators restart at the new one if
        the uninterrupted run's first sample is not behind the checkpoint yet (exact again); otherwise the
        checkpoint's are kept and :attr:`note` says so. A checkpoint written before observables were
        recorded restarts them at the first sample point not yet passed (noted). The layer order, sampled
        from ``t_0`` whatever the transient, always continues the checkpoint's series; a checkpoint without
        one (written before it was recorded) starts it at the first sample point not yet passed (noted).

        Raises:
            ValueError: the checkpoint sampled at another ``sample_interval``.
        """
        last_start = float(records.time[-1]) if records is not None and records.time.size else -math.inf
        wanted = first_sample_index(config.transient_time, sample_interval)

        def not_passed(index: int) -> int:
            """The first sample index from ``index`` on whose point the state has not passed."""
            while stop_time(origin + index * sample_interval, config.time_step) <= last_start:
                index += 1
            return index

        first = not_passed(wanted)  # the first sample point at or after the transient not yet passed
        layer_first = not_passed(0)
        layer_note = ""
        if layer_first:
            layer_note = (
                f"layer order from time {layer_first * sample_interval:g}: the checkpoint holds none before"
            )
        if not saved:
            note = ""
            if first != wanted:
                note = f"observables from strain {first * sample_interval:g}: the checkpoint holds none"
            fresh = cls.fresh(config, sample_interval, first, note, origin)
            fresh.layer_next_index, fresh.layer_note = layer_first, layer_note
            return fresh
        kept = cls.from_arrays(saved)
        kept.origin = float(origin)
        kept.averaging_from_time = origin + config.transient_time
        if kept.layering is None:  # a checkpoint from before the layer order was sampled
            kept.layering = cls._fresh_layering(config)
            kept.layer_next_index, kept.layer_note = layer_first, layer_note
        if kept.sample_interval != sample_interval:
            raise ValueError(
                f"{_name('resume', names)}: the checkpoint sampled observables "
                f"every {kept.sample_interval:g}, but {_name('sample_interval', names)}={sample_interval:g} "
                "was requested"
            )
        if kept.first_index == wanted:
            return kept
        if first == wanted:
            restarted = cls.fresh(config, sample_interval, first, origin=origin)
            restarted.layering = kept.layering  # sampled from t_0: independent of the transient
            restarted.layer_next_index, restarted.layer_note = kept.layer_next_index, kept.layer_note
            return restarted
        kept.note = (
            f"observables from strain {kept.first_index * sample_interval:g} (the transient of the run "
            f"that wrote the checkpoint): this run's transient {config.transient:g} had been passed"
        )
        return kept

    @property
    def next_sample_time(self) -> float:
        """Nominal clock ``t_k`` of the next sample of any kind (the layer order's during the transient)."""
        index = self.next_index if self.layering is None else min(self.next_index, self.layer_next_index)
        return self.origin + index * self.sample_interval

    def _following_index(self, index: int, clock: float, time_step: float) -> int:
        """The index after ``index`` whose sample point ``clock`` has not reached (a step may be longer
        than the interval)."""
        index += 1
        while stop_time(self.origin + index * self.sample_interval, time_step) <= clock:
            index += 1
        return index

    def sample_if_due(self, sim: Simulation) -> bool:
        """Sample ``sim`` if its clock has reached the next ``t_k`` (by the rule of :func:`stop_time`)."""
        config = sim.config
        clock = sim.state.time
        sampled = False
        if self.layering is not None and clock >= stop_time(
            self.origin + self.layer_next_index * self.sample_interval, config.time_step
        ):
            self.layering.add(sim.state.positions, clock, sim.state.strain)
            self.layer_next_index = self._following_index(self.layer_next_index, clock, config.time_step)
            sampled = True
        if clock < stop_time(self.origin + self.next_index * self.sample_interval, config.time_step):
            return sampled
        if (self.next_index - self.first_index) % PAIR_SAMPLE_STRIDE == 0:
            strain = sim.state.strain
            self.pair_distribution.add(sim.state.positions, strain)
            if 2.0 * max(DEFAULT_FABRIC_CUTOFF, 2.0 + DEFAULT_CONTACT_GAP) <= config.box_length:
                self.fabric_sum += fabric_tensor(
                    sim.state.positions, config.box_length, strain, DEFAULT_FABRIC_CUTOFF
                )
                self.contact_sum += contact_number(
                    sim.state.positions, config.box_length, strain, DEFAULT_CONTACT_GAP
                )
                self.structure_samples += 1
        self.msd.add(sim.state.displacement, clock)
        self.next_index = self._following_index(self.next_index, clock, config.time_step)
        return True

    def arrays(self) -> dict[str, np.ndarray]:
        """Arrays for the checkpoint (exact)."""
        return {
            "sample_interval": np.array(self.sample_interval, dtype=np.float64),
            "first_index": np.array(self.first_index, dtype=np.int64),
            "next_index": np.array(self.next_index, dtype=np.int64),
            "note": np.array(self.note),
            **self.pair_distribution.arrays("pair_"),
            **self.msd.arrays("msd_"),
            "fabric_sum": self.fabric_sum,
            "contact_sum": np.array(self.contact_sum, dtype=np.float64),
            "structure_samples": np.array(self.structure_samples, dtype=np.int64),
            **(
                {
                    **self.layering.arrays("layer_"),
                    "layer_next_index": np.array(self.layer_next_index, dtype=np.int64),
                    "layer_note": np.array(self.layer_note),
                }
                if self.layering is not None
                else {}
            ),
        }

    @classmethod
    def from_arrays(cls, data: Mapping[str, np.ndarray]) -> RunObservables:
        """Inverse of :meth:`arrays` (``layering`` None for a checkpoint written before it was sampled)."""
        has_layering = "layer_rows" in data
        return cls(
            sample_interval=float(data["sample_interval"]),
            first_index=int(data["first_index"]),
            next_index=int(data["next_index"]),
            pair_distribution=PairDistributionAccumulator.from_arrays(data, "pair_"),
            msd=MsdAccumulator.from_arrays(data, "msd_"),
            note=str(data["note"]),
            # checkpoints written before the fabric was accumulated hold no sums: start them empty
            fabric_sum=np.array(data["fabric_sum"], dtype=np.float64)
            if "fabric_sum" in data
            else np.zeros((3, 3)),
            contact_sum=float(data["contact_sum"]) if "contact_sum" in data else 0.0,
            structure_samples=int(data["structure_samples"]) if "structure_samples" in data else 0,
            layering=LayerOrderSeries.from_arrays(data, "layer_") if has_layering else None,
            layer_next_index=int(data["layer_next_index"]) if has_layering else 0,
            layer_note=str(data["layer_note"]) if has_layering else "",
        )

    def results(self, config: SimulationConfig) -> dict[str, Any]:
        """The diffusivities, structure, layer order and sampling facts for ``result.json``.

        Layer order (:func:`~sim.observables.layering.summarise_layering`, ``docs/layering.md``):
        ``layer_order`` (mean ``psi = S_peak/N`` over the samples at clock >= the transient),
        ``layer_order_stderr`` (block average, ``config.n_blocks`` blocks, NaN with fewer samples),
        ``layer_spacing`` (units a: spacing of the most frequent peak harmonic there), ``layer_onset_time``
        and ``layer_onset_strain`` (first sample from which ``psi`` stays at or above half the plateau for
        5 samples, when the plateau's ``S_peak`` is at least 10; NaN otherwise), ``layer_axis`` (``"x"``,
        ``"y"`` or ``"z"``), ``layer_samples`` (all samples, transient included) and ``layer_note``.
        """
        unit = "time (a/U0)" if config.quiescent else "strain"
        msd = self.msd
        max_lag_time = msd.max_lag * self.sample_interval
        window = diffusivity_fit_window(msd.span, max_lag_time)
        diffusivity = fit_diffusivity(msd.lag_times, msd.msd, window)
        lags = msd.lag_times
        in_window = int(np.sum((lags >= window[0]) & (lags <= window[1])))
        if msd.count < 2:
            note = (
                f"no diffusivity: {msd.count} displacement sample(s) after the transient (one every "
                f"{self.sample_interval:g} {unit} from {self.first_index * self.sample_interval:g})"
            )
        elif not np.all(np.isfinite(diffusivity)):
            note = (
                f"no diffusivity: the run is too short for the fit window; the MSD spans {msd.span:g} {unit} "
                f"after the transient, and the window [{window[0]:g}, span/{MIN_INDEPENDENT_SEGMENTS}] needs "
                f"a span of at least {2 * MIN_INDEPENDENT_SEGMENTS * DIFFUSIVITY_FIT_START:g}"
            )
        else:
            note = (
                f"D = slope/2 of a least-squares line through MSD(lag) over lags "
                f"[{window[0]:g}, {window[1]:g}] {unit} ({in_window} lags; {msd.count} samples every "
                f"{self.sample_interval:g} from {msd.first_time:g}); x non-affine"
            )
        return {
            "diffusivity_xx": float(diffusivity[0]),
            "diffusivity_yy": float(diffusivity[1]),
            "diffusivity_zz": float(diffusivity[2]),
            "diffusivity_fit_window": [window[0], window[1]],
            "diffusivity_note": note,
            "msd_samples": msd.count,
            "pair_distribution_samples": self.pair_distribution.samples,
            "observables_sample_interval": self.sample_interval,
            "observables_from_strain": self.origin + self.first_index * self.sample_interval,
            "observables_note": self.note,
            "fabric_tensor": (self.fabric_sum / self.structure_samples).tolist()
            if self.structure_samples
            else [[math.nan] * 3] * 3,
            "contact_number": self.contact_sum / self.structure_samples
            if self.structure_samples
            else math.nan,
            "structure_samples": self.structure_samples,
            **self._layer_results(self.averaging_from_time, config.n_blocks),
        }

    def _layer_results(self, from_time: float, n_blocks: int) -> dict[str, Any]:
        """The ``layer_*`` keys of :meth:`results`."""
        if self.layering is None:
            return {}
        summary = summarise_layering(self.layering, from_time, n_blocks)
        return {
            "layer_order": summary.order,
            "layer_order_stderr": summary.order_stderr,
            "layer_spacing": summary.spacing,
            "layer_onset_time": summary.onset_time,
            "layer_onset_strain": summary.onset_strain,
            "layer_axis": AXIS_NAMES[self.layering.axis],
            "layer_samples": len(self.layering.rows),
            "layer_note": self.layer_note,
        }

    def write(self, out: Path) -> None:
        """``pair_distribution.npz``, ``msd.csv``, ``layering.csv`` (columns
        :data:`~sim.observables.layering.LAYER_COLUMNS`) and ``layering.png`` in ``out``."""
        io.write_pair_distribution(out / "pair_distribution.npz", self.pair_distribution.result_arrays())
        io.write_msd(out / "msd.csv", self.msd.lag_times[1:], self.msd.msd[1:])
        if self.layering is not None:
            self.layering.write_csv(out / "layering.csv")
            summary = summarise_layering(self.layering, self.averaging_from_time)
            plot_layering(self.layering, summary, self.averaging_from_time, out / "layering.png")


def _name(parameter: str, names: Mapping[str, str] | None) -> str:
    """How an error message names ``parameter`` (a config field or an argument of ``run_simulation``)."""
    return (names or {}).get(parameter, parameter)
