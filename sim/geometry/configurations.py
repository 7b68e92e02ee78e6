"""Initial configurations: random hard-sphere packings in a cubic box.

:func:`random_packing` places ``N`` unit spheres (``a = 1``) at uniformly random centres in the box of
side :func:`box_length_for` and then removes all overlaps by minimising a soft-sphere energy at a
slightly inflated diameter, in the family of overlap-relaxation packing algorithms (random
placement followed by relaxation of the overlaps; Clarke & Wiley 1987, as cited by Mirfendereski &
Park 2024 §2.3). The minimiser is FIRE (Bitzek et al. 2006) on the harmonic energy of O'Hern et al.
(2003); it finds an overlap-free state at every volume fraction below the jamming point
``phi_J ~ 0.64``, and ``phi <= 0.6`` with ``min_gap = 0.01`` corresponds to an effective volume
fraction of at most ``~0.62``. A final Melrose–Ball sweep
(:func:`~sim.geometry.overlap.remove_overlaps`) guarantees ``r - 2 >= min_gap`` for every pair.

The packings are random, isotropic and deterministic for a given seed, but they are quenched, not
equilibrium hard-sphere states: they carry an excess of near contacts (gaps just above
``min_gap``) compared with the equilibrium contact value of ``g(r)``.

References:
    Clarke, A. S. & Wiley, J. D. (1987) "Numerical simulation of the dense random packing of a binary
    mixture of hard spheres: amorphous metals", Phys. Rev. B 35, 7350. O'Hern, C. S., Silbert, L. E.,
    Liu, A. J. & Nagel, S. R. (2003) "Jamming at zero temperature and zero applied stress: the
    epitome of disorder", Phys. Rev. E 68, 011306. Bitzek, E., Koskinen, P., Gähler, F., Moseler, M.
    & Gumbsch, P. (2006) "Structural relaxation made simple", Phys. Rev. Lett. 97, 170201.
    Mirfendereski, S. & Park, J. S. (2024), J. Fluid Mech., §2.3; ``docs/model.md#time-stepping``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.geometry.box import pair_separation, wrap_positions
from sim.geometry.neighbors import build_pair_list
from sim.geometry.overlap import remove_overlaps

__all__ = ["MAX_VOLUME_FRACTION", "MIN_VOLUME_FRACTION", "box_length_for", "random_packing"]

#: Largest volume fraction :func:`random_packing` accepts.
MAX_VOLUME_FRACTION = 0.6
#: Smallest volume fraction a run accepts (below it the box, and the cell grid of the pair list, grow
#: without bound: phi = 1e-9 with N = 200 would need a 10^5 a box).
MIN_VOLUME_FRACTION = 1.0e-3

# Diameter inflation (units of a) of the soft spheres above 2 + min_gap; FIRE stops when every
# overlap at the inflated diameter is below half of it, so all gaps then exceed min_gap.
_INFLATION = 0.01
# Verlet skin (units of a) of the pair list used during the minimisation.
_SKIN = 0.3
_MAX_FIRE_ITERATIONS = 200_000
_MAX_CLEANUP_SWEEPS = 10_000


def box_length_for(n_particles: int, volume_fraction: float) -> float:
    """Side of the cubic box holding ``n_particles`` unit spheres at ``volume_fraction``.

    ``L = (N*(4/3)*pi/phi)**(1/3)`` (``a = 1``).

    Args:
        n_particles: Number of spheres ``N``, ``>= 1``.
        volume_fraction: Volume fraction ``phi``, in ``(0, 1)``.

    Returns:
        Box side ``L`` (units of ``a``).

    Raises:
        ValueError: If an argument is out of range (the message names it).

    References:
        ``docs/units.md``.
    """
    if isinstance(n_particles, bool) or int(n_particles) != n_particles or n_particles < 1:
        raise ValueError(f"n_particles must be an integer >= 1, got {n_particles!r}")
    volume_fraction = float(volume_fraction)
    if not (0.0 < volume_fraction < 1.0):
        raise ValueError(f"volume_fraction must be in (0, 1), got {volume_fraction!r}")
    return (int(n_particles) * (4.0 / 3.0) * math.pi / volume_fraction) ** (1.0 / 3.0)


@njit(cache=True)
def _relax_soft_spheres(
    positions: np.ndarray,
    box_length: float,
    diameter: float,
    tolerance: float,
    skin: float,
    max_iterations: int,
) -> int:
    """FIRE minimisation of a harmonic soft-sphere energy until every overlap is below ``tolerance``.

    Energy ``E = sum_pairs (1/2) (D - r)^2`` for ``r < D`` (zero offset: no shear), force on ``j``
    ``(D - r) r_hat`` with ``r_hat`` from ``i`` to ``j``; unit masses. FIRE: velocity-Verlet-like
    (semi-implicit Euler) steps with the velocity mixed towards the force direction,
    ``v <- (1 - alpha) v + alpha |v| F/|F|``; ``dt`` grows by 1.1 (up to ``dt_max``) after 5
    downhill steps and halves, with ``v = 0``, on an uphill step (``F.v < 0``).

    Args:
        positions: Centres, shape ``(N, 3)`` float64 (units of ``a``), wrapped; modified in place
            (left wrapped).
        box_length: Box side ``L`` (units of ``a``).
        diameter: Soft-sphere diameter ``D`` (units of ``a``), ``<= L/2``.
        tolerance: Stop when ``max(D - r) <= tolerance`` over all pairs (units of ``a``).
        skin: Verlet skin (units of ``a``), ``D + skin <= L/2``; the list is rebuilt when a sphere
            has moved more than ``skin/2`` since the last build.
        max_iterations: Iteration limit.

    Returns:
        Number of iterations used, or ``-1`` if ``max_iterations`` was reached.

    References:
        O'Hern et al. (2003), Phys. Rev. E 68, 011306; Bitzek et al. (2006), Phys. Rev. Lett. 97,
        170201.
    """
    n = positions.shape[0]
    dt_max = 0.2
    dt = 0.02
    alpha_start = 0.1
    alpha = alpha_start
    n_downhill = 0
    max_step = 0.25 * skin if skin > 0.0 else 0.05
    velocities = np.zeros((n, 3), dtype=np.float64)
    forces = np.zeros((n, 3), dtype=np.float64)
    pairs, _ = build_pair_list(positions, box_length, 0.0, diameter + skin)
    reference = positions.copy()
    half_skin_sq = 0.25 * skin * skin
    for iteration in range(max_iterations):
        forces[:] = 0.0
        max_overlap = 0.0
        for k in range(pairs.shape[0]):
            i = pairs[k, 0]
            j = pairs[k, 1]
            dx, dy, dz, r = pair_separation(positions, i, j, box_length, 0.0)
            overlap = diameter - r
            if overlap <= 0.0:
                continue
            if overlap > max_overlap:
                max_overlap = overlap
            if r > 0.0:
                fx = overlap * dx / r
                fy = overlap * dy / r
                fz = overlap * dz / r
            else:
                fx = overlap
                fy = 0.0
                fz = 0.0
            forces[i, 0] -= fx
            forces[i, 1] -= fy
            forces[i, 2] -= fz
            forces[j, 0] += fx
            forces[j, 1] += fy
            forces[j, 2] += fz
        if max_overlap <= tolerance:
            wrap_positions(positions, box_length, 0.0)
            return iteration
        power = 0.0
        v_norm_sq = 0.0
        f_norm_sq = 0.0
        for i in range(n):
            for d in range(3):
                power += forces[i, d] * velocities[i, d]
                v_norm_sq += velocities[i, d] * velocities[i, d]
                f_norm_sq += forces[i, d] * forces[i, d]
        if power > 0.0:
            mix = alpha * math.sqrt(v_norm_sq / f_norm_sq) if f_norm_sq > 0.0 else 0.0
            for i in range(n):
                for d in range(3):
                    velocities[i, d] = (1.0 - alpha) * velocities[i, d] + mix * forces[i, d]
            n_downhill += 1
            if n_downhill > 5:
                dt = min(1.1 * dt, dt_max)
                alpha *= 0.99
        else:
            velocities[:] = 0.0
            dt *= 0.5
            alpha = alpha_start
            n_downhill = 0
        max_disp_sq = 0.0
        for i in range(n):
            vx = velocities[i, 0] + dt * forces[i, 0]
            vy = velocities[i, 1] + dt * forces[i, 1]
            vz = velocities[i, 2] + dt * forces[i, 2]
            step = dt * math.sqrt(vx * vx + vy * vy + vz * vz)
            if step > max_step:  # cap single steps (large initial overlaps)
                scale = max_step / step
                vx *= scale
                vy *= scale
                vz *= scale
            velocities[i, 0] = vx
            velocities[i, 1] = vy
            velocities[i, 2] = vz
            positions[i, 0] += dt * vx
            positions[i, 1] += dt * vy
            positions[i, 2] += dt * vz
            ex = positions[i, 0] - reference[i, 0]
            ey = positions[i, 1] - reference[i, 1]
            ez = positions[i, 2] - reference[i, 2]
            disp_sq = ex * ex + ey * ey + ez * ez
            if disp_sq > max_disp_sq:
                max_disp_sq = disp_sq
        if max_disp_sq > half_skin_sq:
            wrap_positions(positions, box_length, 0.0)
            pairs, _ = build_pair_list(positions, box_length, 0.0, diameter + skin)
            reference[:] = positions
    wrap_positions(positions, box_length, 0.0)
    return -1


def random_packing(n_particles: int, volume_fraction: float, seed: int, min_gap: float = 1e-2) -> np.ndarray:
    """Random packing of ``n_particles`` unit spheres at ``volume_fraction`` with every gap ``>= min_gap``.

    Centres are drawn uniformly in ``[0, L)^3`` with ``np.random.default_rng(seed)``, then the
    overlaps are relaxed by FIRE minimisation of a harmonic soft-sphere energy at diameter
    ``D = 2 + min_gap + 0.01`` (O'Hern et al. 2003; Bitzek et al. 2006) until every overlap at
    ``D`` is below ``0.005``, and a Melrose–Ball sweep enforces ``r - 2 >= min_gap`` exactly. The
    result is deterministic for a given ``seed`` (serial numba kernels, no other randomness).

    Args:
        n_particles: Number of spheres ``N``, an integer ``>= 2``.
        volume_fraction: Volume fraction ``phi = N (4/3) pi / L^3``, in ``(0, 0.6]``.
        seed: Seed for ``np.random.default_rng``.
        min_gap: Smallest surface gap ``r - 2`` (units of ``a``), finite, in ``[0, 0.1]``.

    Returns:
        Centres, shape ``(N, 3)`` float64 (units of ``a``), wrapped into ``[0, L)^3`` with
        ``L = box_length_for(n_particles, volume_fraction)`` (zero Lees–Edwards offset).

    Raises:
        ValueError: If ``n_particles``, ``volume_fraction`` or ``min_gap`` is out of range, or if
            the box is too small (``L/2 < 2 + min_gap + 1e-6``, i.e. too few particles at this
            volume fraction for the minimum image to give every pair's true gap).
        RuntimeError: If the relaxation fails to converge (not expected for ``phi <= 0.6``).

    References:
        Clarke & Wiley (1987), Phys. Rev. B 35, 7350; O'Hern et al. (2003), Phys. Rev. E 68,
        011306; Bitzek et al. (2006), Phys. Rev. Lett. 97, 170201; Mirfendereski & Park (2024),
        J. Fluid Mech., §2.3.
    """
    if isinstance(n_particles, bool) or int(n_particles) != n_particles or n_particles < 2:
        raise ValueError(f"n_particles must be an integer >= 2, got {n_particles!r}")
    n_particles = int(n_particles)
    volume_fraction = float(volume_fraction)
    if not (0.0 < volume_fraction <= MAX_VOLUME_FRACTION):
        raise ValueError(f"volume_fraction must be in (0, {MAX_VOLUME_FRACTION}], got {volume_fraction!r}")
    min_gap = float(min_gap)
    if not (math.isfinite(min_gap) and 0.0 <= min_gap <= 0.1):
        raise ValueError(f"min_gap must be in [0, 0.1], got {min_gap!r}")
    box_length = box_length_for(n_particles, volume_fraction)
    contact = 2.0 + min_gap + 1e-6
    if 0.5 * box_length < contact:
        n_min = math.ceil((2.0 * contact) ** 3 * volume_fraction / ((4.0 / 3.0) * math.pi))
        raise ValueError(
            f"box too small: n_particles = {n_particles} at volume_fraction = {volume_fraction} gives "
            f"L = {box_length:.4g} < 2*(2 + min_gap); use n_particles >= {n_min} at this volume_fraction"
        )
    # Inflation and skin shrink in boxes barely larger than 2*(2 + min_gap) so that D + skin <= L/2.
    inflation = min(_INFLATION, 0.5 * box_length - contact)
    diameter = 2.0 + min_gap + inflation
    skin = min(_SKIN, 0.5 * box_length - diameter)
    rng = np.random.default_rng(seed)
    positions = rng.uniform(0.0, box_length, size=(n_particles, 3))
    wrap_positions(positions, box_length, 0.0)
    iterations = _relax_soft_spheres(
        positions, box_length, diameter, 0.5 * inflation, skin, _MAX_FIRE_ITERATIONS
    )
    if iterations < 0:
        raise RuntimeError(
            f"random_packing: soft-sphere relaxation did not converge in {_MAX_FIRE_ITERATIONS} "
            f"iterations (n_particles = {n_particles}, volume_fraction = {volume_fraction})"
        )
    sweeps, _ = remove_overlaps(positions, box_length, 0.0, min_gap, _MAX_CLEANUP_SWEEPS)
    if sweeps < 0:
        raise RuntimeError(
            f"random_packing: overlap removal did not converge in {_MAX_CLEANUP_SWEEPS} sweeps "
            f"(n_particles = {n_particles}, volume_fraction = {volume_fraction})"
        )
    return positions
