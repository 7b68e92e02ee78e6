"""Stokesian-dynamics simulator of ideally conductive spheres under shear (public API).

Units: sphere radius ``a = 1``, viscosity ``eta = 1``, shear rate ``gammadot = 1`` (time is strain, stress
is in ``eta gammadot``). Axes: x flow, y velocity gradient, z vorticity.

``dipenv`` and ``agents`` use only the names exported here.
"""

__version__ = "0.1.0"

from sim.numba_cache import configure_numba_cache

NUMBA_CACHE_DIR = configure_numba_cache()

# isort: off
# The order of these imports is part of the start-state library's key (dipenv.state_library digests this
# file's syntax tree; DIGESTED_UNDER_FORMER_NAME maps the sim.runs names to their former ones): sorted, the
# three sim.runs lines would move and every cached start state would be generated again.
from sim.config import MAX_SHEAR_RATE, MECHANISMS, MIN_SHEAR_RATE, NEAR_FIELD_MODELS, SimulationConfig
from sim.geometry.box import LeesEdwardsBox
from sim.geometry.configurations import box_length_for, random_packing
from sim.runs.io import versions
from sim.observables.diffusion import (
    MsdAccumulator,
    accumulate_displacement,
    diffusivity_fit_window,
    fit_diffusivity,
    mean_square_displacement,
)
from sim.observables.interparticle_stress import InterparticleStress, interparticle_stress
from sim.observables.microstructure import angular_pair_distribution, contact_number, fabric_tensor
from sim.observables.pair_distribution import PairDistributionAccumulator, pair_histograms
from sim.observables.stress import STRESS_CONTRIBUTIONS, BlockAverage, block_average, rheology
from sim.runs.run import COMPILE_NOTICE, compiled_kernels_cached, run_simulation
from sim.simulation import RheologyResult, Simulation, SimulationError, StepRecords, summarise
from sim.state import SimulationState
from sim.runs.tasks import TaskFailure, parse_seeds, run_tasks
from sim.variants import PiecewiseLinear, constant, follow, pieces, ramp, schedule_from_segments
# isort: on

__all__ = [
    "COMPILE_NOTICE",
    "compiled_kernels_cached",
    "PiecewiseLinear",
    "constant",
    "follow",
    "pieces",
    "ramp",
    "schedule_from_segments",
    "MECHANISMS",
    "MAX_SHEAR_RATE",
    "MIN_SHEAR_RATE",
    "NEAR_FIELD_MODELS",
    "STRESS_CONTRIBUTIONS",
    "BlockAverage",
    "InterparticleStress",
    "LeesEdwardsBox",
    "RheologyResult",
    "Simulation",
    "SimulationConfig",
    "SimulationError",
    "SimulationState",
    "StepRecords",
    "__version__",
    "block_average",
    "box_length_for",
    "interparticle_stress",
    "random_packing",
    "rheology",
    "run_simulation",
    "summarise",
    "versions",
    "angular_pair_distribution",
    "contact_number",
    "fabric_tensor",
    "MsdAccumulator",
    "PairDistributionAccumulator",
    "TaskFailure",
    "accumulate_displacement",
    "diffusivity_fit_window",
    "fit_diffusivity",
    "mean_square_displacement",
    "pair_histograms",
    "parse_seeds",
    "run_tasks",
]
