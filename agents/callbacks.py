"""Callbacks: log the physics of each step (from the env's ``info``) to the SB3 logger / TensorBoard."""

from __future__ import annotations

import math

from stable_baselines3.common.callbacks import BaseCallback


class PhysicsLoggerCallback(BaseCallback):
    """Record means of ``eta_r``, ``log10 Mn`` (field on), the field-on fraction, the field energy, the
    reward terms and the count of simulator failures under ``physics/`` at every logger dump."""

    def __init__(self, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.failures = 0

    def _on_step(self) -> bool:
        for info in self.locals.get("infos", []):
            if info.get("simulation_failed"):
                self.failures += 1
                self.logger.record("physics/simulation_failures", self.failures)
                continue
            if "eta_r" not in info or "field_energy" not in info:
                continue
            self.logger.record_mean("physics/eta_r", float(info["eta_r"]))
            self.logger.record_mean("physics/field_energy", float(info["field_energy"]))
            mn = float(info["mason_number"])
            self.logger.record_mean("physics/field_on", 0.0 if math.isinf(mn) else 1.0)
            if math.isfinite(mn):
                self.logger.record_mean("physics/log10_mason", math.log10(mn))
            for key in ("reward_viscosity", "reward_energy", "sim_steps"):
                if key in info:
                    self.logger.record_mean(f"physics/{key}", float(info[key]))
        return True
