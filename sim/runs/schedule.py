"""When a run keeps something at multiples of its strain: snapshots and trajectory frames.

A run's length is counted in strain (in time, units ``a/U0``, when it is quiescent: ``shear_rate = 0``,
where ``--strain`` is a time). :class:`StrainMultiples` names the points ``k * every`` of that coordinate
and the clock at which the run reaches each. As for the observables (:mod:`sim.runs.observables`), the
step loop stops at the first step that reaches a point (stopping never changes the trajectory), so the
state kept for point ``k`` is the one at the first step at or beyond it; a step longer than ``every``
passes several points at once, and the state is then kept once, for the first of them. The one rule for
"reached" is :func:`sim.stepper.stop_time` (a point counts as reached ``1e-9`` of a step early, so that
round-off in the accumulated clock never adds a step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.stepper import stop_time


def multiples_decimals(every: float) -> int:
    """Decimals (0 to 6) that print every multiple of ``every`` (a strain) exactly enough to tell them
    apart: 0 for whole strains, 1 for 0.5, 2 for 0.25, ..."""
    for decimals in range(7):
        if abs(round(every, decimals) - every) <= 1e-9 * every:
            return decimals
    return 6


@dataclass
class StrainMultiples:
    """The points ``k * every`` of a run's length coordinate from where the run starts on, and the next one
    not reached yet.

    Attributes:
        every: spacing of the points (strain; time when quiescent), > 0.
        start_clock: the clock at which the run started, ``t_0`` (units ``1/gammadot_ref``).
        start_length: the run's length coordinate there: its strain ``gamma_0`` (its clock when quiescent).
        shear_rate: the run's (constant) shear rate ``gammadot / gammadot_ref``; 0: quiescent, the length
            coordinate is the clock.
        time_step: the run's largest step (the slack of :func:`~sim.stepper.stop_time`).
        next_index: ``k`` of the next point not reached yet.
    """

    every: float
    start_clock: float
    start_length: float
    shear_rate: float
    time_step: float
    next_index: int = 0

    @classmethod
    def for_run(
        cls,
        every: float,
        start_clock: float,
        start_length: float,
        shear_rate: float,
        time_step: float,
        clock: float | None = None,
        include_start: bool = True,
    ) -> StrainMultiples:
        """The points of a run that started at ``(start_clock, start_length)``.

        Args:
            include_start: whether a point at the starting state itself counts (trajectories: the first
                frame is the starting configuration when it sits on a multiple, as a fresh run's strain 0
                does; snapshots: no, the starting state is the run's input).
            clock: where a resumed run is (its checkpoint's clock): the points it has reached were kept
                before that checkpoint was written, so the next one is the first it has not reached.
                ``None``: a run at its start, nothing kept yet.
        """
        schedule = cls(
            float(every), float(start_clock), float(start_length), float(shear_rate), float(time_step)
        )
        first = max(math.ceil(start_length / every - 1e-9), 0)
        if not include_start and first * every <= start_length + 1e-9 * every:
            first += 1
        schedule.next_index = first
        if clock is not None:
            schedule.next_index = schedule._following(first - 1, clock)
        return schedule

    def length_at(self, index: int) -> float:
        """The point ``index * every`` (strain; time when quiescent)."""
        return index * self.every

    def clock_of(self, index: int) -> float:
        """The clock at which the run reaches the point ``index`` (its rate is constant)."""
        length = self.length_at(index)
        if self.shear_rate > 0.0:
            return self.start_clock + (length - self.start_length) / self.shear_rate
        return length

    @property
    def next_clock(self) -> float:
        """The clock of the next point not reached yet."""
        return self.clock_of(self.next_index)

    def reached(self, index: int, clock: float) -> bool:
        """Whether a run at ``clock`` has reached the point ``index`` (:func:`~sim.stepper.stop_time`)."""
        return clock >= stop_time(self.clock_of(index), self.time_step)

    def _following(self, index: int, clock: float) -> int:
        """The first point after ``index`` that ``clock`` has not reached."""
        index += 1
        while self.reached(index, clock):
            index += 1
        return index

    def due(self, clock: float) -> int | None:
        """The point to keep the state at ``clock`` for (the first reached and not yet kept), or None; the
        points it passes are marked as kept."""
        if not self.reached(self.next_index, clock):
            return None
        index = self.next_index
        self.next_index = self._following(index, clock)
        return index
