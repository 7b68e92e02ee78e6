"""Real-space Ewald sums over several periodic images (issue 22): small boxes, ``r_c > L/2``.

A box of ``L = 8.4 a`` (N = 64 at phi = 0.45) used to cap the real-space cut-off at ``L/2``; the sums
now take every image within ``r_c`` (Lees–Edwards images shifted by the offset), so the plan can take a
smaller splitting parameter and far fewer wave vectors. Checked here: the real-space sums against a
brute-force sum over explicit lattice images (any ``r_c``, sheared lattices, a sphere's own images),
the plan's accuracy in a small box against a converged nearest-image reference, splitting
independence across the two regimes, and that large boxes keep their nearest-image plans.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_ewald import hard_sphere_configuration

from sim.dipolophoresis.ewald import (
    METHOD_EWALD,
    EwaldPlan,
    _real_space_block,
    _real_space_sums,
    dip_far_field,
    ewald_plan,
)
from sim.geometry.box import lees_edwards_offset
from sim.geometry.configurations import box_length_for, random_packing

E_Y = np.array([0.0, 1.0, 0.0])
E_GENERIC = np.array([0.3, 0.8, -0.2]) / np.linalg.norm([0.3, 0.8, -0.2])


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(v * v, axis=1))))


def _q(e: np.ndarray) -> np.ndarray:
    return np.outer(e, e) - np.eye(3) / 3.0


def _brute_force_real_space(
    positions: np.ndarray, box: float, offset: float, xi: float, cutoff: float, e: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Real-space sums over explicit lattice images ``(n1 L + n2 delta, n2 L, n3 L)`` within ``cutoff``.

    Every pair ``alpha < beta`` with every image, and every sphere with its own images ``n != 0`` in a
    half space (each ``+-n`` once), evaluated by the same pair block as the cell-list code.
    """
    n = positions.shape[0]
    reach = int(math.ceil(cutoff / box)) + 2
    r = np.arange(-reach, reach + 1)
    n1, n2, n3 = (a.ravel() for a in np.meshgrid(r, r, r, indexing="ij"))
    lattice = np.stack([box * n1 + offset * n2, box * n2, box * n3], axis=1)
    half = (n2 > 0) | ((n2 == 0) & (n3 > 0)) | ((n2 == 0) & (n3 == 0) & (n1 > 0))
    alphas, betas, seps = [], [], []
    for a in range(n):
        for b in range(a, n):
            x = positions[a] - positions[b] + (lattice if b > a else lattice[half])
            keep = np.einsum("ij,ij->i", x, x) < cutoff * cutoff
            seps.append(x[keep])
            alphas += [a] * int(keep.sum())
            betas += [b] * int(keep.sum())
    x = np.concatenate(seps)
    m = x.shape[0]
    r2 = np.einsum("ij,ij->i", x, x)
    q = _q(e)
    ux, uy, uz = np.empty(m), np.empty(m), np.empty(m)
    sums = _real_space_block(
        m,
        x[:, 0].copy(),
        x[:, 1].copy(),
        x[:, 2].copy(),
        r2,
        np.exp(-xi * xi * r2),
        xi,
        (q[0, 0], q[0, 1], q[0, 2], q[1, 1], q[1, 2], q[2, 2]),
        -1.125,
        -0.375,
        ux,
        uy,
        uz,
        np.empty(m),
    )
    u = np.stack([ux, uy, uz], axis=1)
    velocity = np.zeros((n, 3))
    np.add.at(velocity, np.array(alphas), u)
    np.add.at(velocity, np.array(betas), -u)
    return velocity, np.array(sums).reshape(2, 6)


@pytest.mark.parametrize(
    ("n", "phi", "cutoff_over_box", "strain"),
    [
        (64, 0.45, 0.86, 0.37),  # the N = 64 plan's regime: several images, none of a sphere itself
        (64, 0.45, 0.86, -0.5),
        (20, 0.3, 1.4, 0.23),  # r_c > L: own images too
        (1, 0.05, 1.45, 0.41),  # a single sphere: only its own images
        (200, 0.3, 0.45, 0.37),  # r_c < L/2: the nearest-image cell list (>= 3 cells per axis)
        (60, 0.3, 0.45, -0.29),  # r_c < L/2 with fewer than 3 cells per axis (minimum image)
    ],
)
def test_real_space_sums_equal_brute_force_images(
    n: int, phi: float, cutoff_over_box: float, strain: float
) -> None:
    """Cell-list real-space sums == explicit sum over lattice images (velocities, both stress sums): 1e-12."""
    if n == 1:
        positions, box = np.array([[0.3, 1.2, 2.2]]), (4.0 / 3.0 * math.pi / phi) ** (1.0 / 3.0)
    else:
        positions, box = hard_sphere_configuration(n, phi, 30 + n)
    offset = float(lees_edwards_offset(strain, box))
    xi = 0.7
    cutoff = cutoff_over_box * box
    velocity = np.zeros((n, 3))
    sums = np.zeros((2, 6))
    _real_space_sums(positions, box, offset, xi, cutoff, _q(E_GENERIC), -1.125, -0.375, velocity, sums)
    ref_velocity, ref_sums = _brute_force_real_space(positions, box, offset, xi, cutoff, E_GENERIC)
    scale = max(np.abs(ref_velocity).max(), 1e-300)
    assert np.abs(velocity - ref_velocity).max() <= 1e-12 * scale + (1e-15 if n == 1 else 0.0)
    assert np.abs(sums - ref_sums).max() <= 1e-12 * np.abs(ref_sums).max()


def _converged_nearest_image(box: float) -> EwaldPlan:
    """A nearest-image plan (``r_c = L/2``, large ``xi``) converged to ~1e-13 of the velocities."""
    return EwaldPlan(2.0, 0.5 * box, 30.0, METHOD_EWALD, (0, 0, 0), 0, box)


@pytest.mark.parametrize("strain", [0.0, 0.37, -0.5])
def test_small_box_plan_meets_accuracy(strain: float) -> None:
    """N = 64, phi = 0.45 (L = 8.4): the default plan sums several images (r_c > L/2, xi ~ 0.6, < 1000 waves)
    and keeps the stated accuracy: rms velocity error < 1e-6 rms velocity against a converged
    nearest-image reference at Lees–Edwards offsets 0, 0.37 L, -L/2; stress sums within 1e-5."""
    n = 64
    box = box_length_for(n, 0.45)
    positions = random_packing(n, 0.45, 1)
    plan = ewald_plan(box, n, 1e-6, "ewald")
    assert plan.real_cutoff > 0.5 * box
    assert plan.splitting < 0.7
    assert (2.0 * math.pi / 3.0) * (plan.k_cutoff * box / (2.0 * math.pi)) ** 3 < 1000
    offset = float(lees_edwards_offset(strain, box))
    v, icep, dep = dip_far_field(positions, box, offset, E_Y, 1.0, 1.0, plan)
    rv, ricep, rdep = dip_far_field(positions, box, offset, E_Y, 1.0, 1.0, _converged_nearest_image(box))
    assert _rms(v - rv) < 1e-6 * _rms(rv)
    assert np.abs(icep - ricep).max() < 1e-5 * np.abs(ricep).max()
    assert np.abs(dep - rdep).max() < 1e-5 * np.abs(rdep).max()


@pytest.mark.parametrize(("n", "phi"), [(64, 0.45), (20, 0.3), (1, 0.05)])
def test_splitting_independence_across_image_regimes(n: int, phi: float) -> None:
    """A converged sum over images up to r_c = 1.45 L (a sphere's own images included) equals the
    converged nearest-image sum (r_c = L/2): velocities 1e-10 relative, stress sums 1e-10 of the largest
    component (as test_ewald.test_splitting_independence), on a sheared lattice with a generic field
    direction (measured 1e-13..3e-11: rounding in the ~60,000 wave vectors of the reference)."""
    if n == 1:
        positions, box = np.array([[0.3, 1.2, 2.2]]), (4.0 / 3.0 * math.pi / phi) ** (1.0 / 3.0)
    else:
        positions, box = hard_sphere_configuration(n, phi, 40 + n)
    offset = float(lees_edwards_offset(0.37, box))
    xi = 6.5 / (1.45 * box)  # xi r_c = 6.5, k_c^2/(4 xi^2) = 42: converged to ~1e-15
    images = EwaldPlan(xi, 1.45 * box, 13.0 * xi, METHOD_EWALD, (0, 0, 0), 0, box)
    v, icep, dep = dip_far_field(positions, box, offset, E_GENERIC, 1.0, 1.0, images)
    rv, ricep, rdep = dip_far_field(
        positions, box, offset, E_GENERIC, 1.0, 1.0, _converged_nearest_image(box)
    )
    if n > 1:
        assert np.abs(v - rv).max() <= 1e-10 * _rms(rv)
    assert np.abs(icep - ricep).max() <= 1e-10 * np.abs(ricep).max()
    assert np.abs(dep - rdep).max() <= 1e-10 * np.abs(rdep).max()


@pytest.mark.parametrize("n", [500, 1000])
def test_large_box_plans_unchanged(n: int) -> None:
    """Large boxes keep their nearest-image plans: r_c <= L/2 and xi on the grid the plan always
    scanned (4/L times 40 geometric steps up to 12), i.e. the plan of the nearest-image code."""
    box = box_length_for(n, 0.45)
    plan = ewald_plan(box, n, 1e-6, "ewald")
    assert plan.real_cutoff <= 0.5 * box
    grid = 4.0 / box * np.geomspace(1.0, 12.0, 40)
    assert np.min(np.abs(grid - plan.splitting)) == 0.0
