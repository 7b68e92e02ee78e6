"""The exact near field blended into the periodic far field (sim/dipolophoresis/near_field_blend.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim import SimulationConfig
from sim.dipolophoresis.far_field import MECHANISM_WEIGHTS, far_field_functions
from sim.dipolophoresis.near_field import pair_functions
from sim.dipolophoresis.near_field_blend import blend_weight
from sim.step_parameters import field_parameters, run_ewald_plan, step_parameters
from sim.stepper import evaluate

FAR_CODES = {"dip": 0, "icep": 1, "dep": 2}


def _dip_velocity(config: SimulationConfig, positions: np.ndarray, e: np.ndarray) -> np.ndarray:
    params = step_parameters(config)
    field = field_parameters(config, config.mason_number, e, run_ewald_plan(config))
    n = positions.shape[0]
    _, _, dip, _, _, _ = evaluate(np.ascontiguousarray(positions), 0.0, np.zeros((n, 6)), params, field)
    return dip


def _pair(r: float, angle_deg: float, length: float) -> tuple[np.ndarray, np.ndarray]:
    th = math.radians(angle_deg)
    xh = np.array([math.sin(th) * math.cos(0.3), math.cos(th), math.sin(th) * math.sin(0.3)])
    centre = np.full(3, length / 2)
    return np.array([centre + 0.5 * r * xh, centre - 0.5 * r * xh]), xh  # alpha = 0, x = x0 - x1 = r xh


def test_blend_weight_is_c1() -> None:
    """w = 1 below r_c - width, 0 above r_c; value and slope continuous at both ends (1e-6 steps)."""
    r_cut, width = 4.0, 0.5
    assert blend_weight(3.4, r_cut, width) == 1.0 and blend_weight(4.0, r_cut, width) == 0.0
    for edge in (r_cut - width, r_cut):
        h = 1e-6
        left, mid, right = (blend_weight(edge + k * h, r_cut, width) for k in (-1, 0, 1))
        assert abs(right - left) < 1e-5
        assert abs((right - mid) - (mid - left)) < 1e-9  # slope continuous (second difference ~ h^2)


@pytest.mark.parametrize("mechanism", ["dip", "icep", "dep"])
@pytest.mark.parametrize("r,angle", [(2.01, 20.0), (2.3, 60.0), (3.2, 85.0)])
def test_correction_equals_exact_minus_far_field(mechanism: str, r: float, angle: float) -> None:
    """Inside r_c - width the exact-minus-none difference of U^d is exactly the isolated pair's
    (exact - far field) velocity from the public pair functions (1e-12, rounding): the periodic images
    cancel in the difference; U_beta = -U_alpha for the correction."""
    base = dict(n_particles=2, volume_fraction=0.002, mason_number=1.0, shear_rate=0, mechanism=mechanism)
    exact_cfg = SimulationConfig(**base, near_field="exact")
    none_cfg = SimulationConfig(**base, near_field="none")
    e = np.array([0.0, 1.0, 0.0])
    positions, xh = _pair(r, angle, exact_cfg.box_length)
    du = _dip_velocity(exact_cfg, positions, e) - _dip_velocity(none_cfg, positions, e)
    exact = np.array(pair_functions(r, mechanism))
    far = np.array(far_field_functions(r, FAR_CODES[mechanism]))
    d_par, d_perp, d_x = exact - far
    c = float(e @ xh)
    expected = (d_par * c * c + d_perp * (1 - c * c)) * xh + 2 * d_x * c * (e - c * xh)
    np.testing.assert_allclose(du[0], expected, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(du[1], -expected, rtol=1e-10, atol=1e-13)
    assert MECHANISM_WEIGHTS[mechanism]  # names agree between the modules


def test_no_jump_at_the_cutoff() -> None:
    """A pair just inside and just outside r_c: U^d differs by O(dr) only (no step), 1e-7 for dr = 2e-9."""
    config = SimulationConfig(n_particles=2, volume_fraction=0.002, mason_number=1.0, shear_rate=0)
    e = np.array([0.0, 1.0, 0.0])
    r_cut = config.near_field_cutoff
    inside, _ = _pair(r_cut - 1e-9, 40.0, config.box_length)
    outside, _ = _pair(r_cut + 1e-9, 40.0, config.box_length)
    assert np.abs(_dip_velocity(config, inside, e) - _dip_velocity(config, outside, e)).max() < 1e-7


def test_small_box_with_exact_near_field_is_refused() -> None:
    with pytest.raises(ValueError, match="near_field_cutoff"):
        SimulationConfig(n_particles=20, volume_fraction=0.45, mason_number=1.0)
    SimulationConfig(n_particles=20, volume_fraction=0.45, mason_number=1.0, near_field="none")


def _basis(f: tuple[float, float, float, float], e: np.ndarray, xh: np.ndarray) -> np.ndarray:
    """f1 (ee - I/3) + f2 [c (e xh + xh e) - 2/3 c^2 I] + (f3 + f4 c^2)(xh xh - I/3)."""
    c = float(e @ xh)
    eye = np.eye(3)
    return (
        f[0] * (np.outer(e, e) - eye / 3)
        + f[1] * (c * (np.outer(e, xh) + np.outer(xh, e)) - 2 / 3 * c * c * eye)
        + (f[2] + f[3] * c * c) * (np.outer(xh, xh) - eye / 3)
    )


@pytest.mark.parametrize("r,angle", [(2.02, 25.0), (2.7, 70.0)])
def test_stress_correction_equals_exact_minus_far_field(r: float, angle: float) -> None:
    """Isolated pair, field on (Mn = 1, quiescent units eps E0^2): the exact-minus-none difference of each
    DIP stress slot equals, from the public table functions and docs/model.md#dip-far-field's far-field forms,
    icep_pair: 2 pi (dS^exact - dS^far) / V; dep_virial: -pi sym(x (F^exact - F^far)) / V;
    dep_stresslet: 2 pi S^DEP / V (1e-10 relative: rounding)."""
    from sim.dipolophoresis.near_field_stress import dep_force_functions, pair_stress_functions
    from sim.observables.stress import STRESS_CONTRIBUTIONS
    from sim.step_parameters import field_parameters, run_ewald_plan, step_parameters

    base = dict(n_particles=2, volume_fraction=0.002, mason_number=1.0, shear_rate=0)
    e = np.array([0.0, 1.0, 0.0])
    stresses = {}
    for near_field in ("exact", "none"):
        config = SimulationConfig(**base, near_field=near_field)
        positions, xh = _pair(r, angle, config.box_length)
        field = field_parameters(config, 1.0, e, run_ewald_plan(config))
        _, _, _, stress, _, _ = evaluate(positions, 0.0, np.zeros((2, 6)), step_parameters(config), field)
        stresses[near_field] = stress
    volume = config.box_length**3
    diff = stresses["exact"] - stresses["none"]
    icep_far = (9.0, -36.0, -22.5, 112.5)
    d_icep = _basis(pair_stress_functions(r, "icep"), e, xh) - _basis(
        tuple(f / r**3 for f in icep_far), e, xh
    )
    s_dep = _basis(pair_stress_functions(r, "dep"), e, xh)
    c = float(e @ xh)
    f_par, f_perp, f_x = dep_force_functions(r)
    force = (f_par * c * c + f_perp * (1 - c * c)) * xh + 2 * f_x * c * (e - c * xh)
    force_far = -3.0 * ((5 * c * c - 1) * xh - 2 * c * e) / r**4
    x = r * xh
    d_virial = -0.5 * (np.outer(x, force - force_far) + np.outer(force - force_far, x))
    index = {name: STRESS_CONTRIBUTIONS.index(name) for name in ("icep_pair", "dep_virial", "dep_stresslet")}
    scale = math.pi / volume
    np.testing.assert_allclose(diff[index["icep_pair"]], 2 * scale * d_icep, rtol=1e-10, atol=1e-16)
    np.testing.assert_allclose(diff[index["dep_virial"]], scale * d_virial, rtol=1e-10, atol=1e-16)
    np.testing.assert_allclose(diff[index["dep_stresslet"]], 2 * scale * s_dep, rtol=1e-10, atol=1e-16)
    assert np.abs(diff[index["icep_pair"]]).max() > 1e-6  # the correction is not trivially zero


@pytest.mark.parametrize("near_code", [0, 1, 2])
def test_near_contact_functions_match_the_table_kernels(near_code: int) -> None:
    """Below the first table node the blend evaluates all 16 near-contact forms from one logarithm
    (``exp(p ln xi)`` for ``xi^p``); independent numbers: the tables' own kernels (``pow`` per function),
    at gaps from below the floor (1e-7) to just under the first node, to 1e-13 relative."""
    from sim.dipolophoresis.near_field import near_field_kernel
    from sim.dipolophoresis.near_field_blend import _pair_functions
    from sim.dipolophoresis.near_field_stress import dep_force_kernel, near_field_stress_kernel
    from sim.step_parameters import NEAR_FIELD_TABLES

    grid, coefficients, asymptotics, stress_grid, stress_coefficients, stress_asymptotics = NEAR_FIELD_TABLES
    want_icep, want_dep = near_code != 1, near_code != 0
    gaps = np.concatenate([np.geomspace(1e-7, 0.999 * grid[4], 40), [grid[5], 0.5 * grid[5]]])
    for gap in gaps:
        r = 2.0 + gap
        got = np.array(_pair_functions(r, near_code, want_icep, want_dep, NEAR_FIELD_TABLES))
        velocity = near_field_kernel(r, near_code, grid, coefficients, asymptotics)
        icep = near_field_stress_kernel(r, 0, stress_grid, stress_coefficients, stress_asymptotics)
        dep = near_field_stress_kernel(r, 1, stress_grid, stress_coefficients, stress_asymptotics)
        force = dep_force_kernel(r, stress_grid, stress_coefficients, stress_asymptotics)
        expected = np.array(
            [*velocity, *(icep if want_icep else (0.0,) * 4), *(dep if want_dep else (0.0,) * 4)]
            + list(force if want_dep else (0.0,) * 3)
        )
        np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13 * np.abs(expected).max())


@pytest.mark.parametrize(("n", "accuracy"), [(64, 1e-4), (64, 1e-6), (300, 1e-4)])
def test_real_space_sum_hands_over_the_near_pairs(n: int, accuracy: float) -> None:
    """The pairs closer than the blend's cut-off, as the Ewald real-space sum collects them (cell order,
    several images per pair at N = 64 where r_c > L/2), against the independent cell-list pair list
    ``build_pair_list``: the same set of pairs, separations to 1e-12 a, and the blended DIP velocities
    and stresses from either list equal to 1e-12 relative."""
    from sim.dipolophoresis.ewald import collects_near_pairs, dip_far_field_with_pairs, ewald_plan
    from sim.dipolophoresis.near_field_blend import add_near_field_corrections, add_pair_corrections
    from sim.geometry.box import lees_edwards_offset
    from sim.geometry.configurations import random_packing
    from sim.geometry.neighbors import build_pair_list
    from sim.step_parameters import NEAR_FIELD_TABLES

    positions = random_packing(n, 0.45, 5, min_gap=1e-4)
    box = SimulationConfig(n_particles=n, volume_fraction=0.45).box_length
    plan = ewald_plan(box, n, accuracy)
    e = np.array([0.0, 1.0, 0.0])
    for strain in (0.0, 0.37, 0.81):
        offset = float(lees_edwards_offset(strain, box))
        assert collects_near_pairs(plan, box, 4.0)
        v, icep, dep, pairs, seps = dip_far_field_with_pairs(positions, box, offset, e, 1.0, 1.0, plan, 4.0)
        ref_pairs, ref_seps = build_pair_list(positions, box, offset, 4.0)
        flip = pairs[:, 0] > pairs[:, 1]
        ordered = np.where(flip[:, None], pairs[:, ::-1], pairs)
        signed = np.where(flip[:, None], -seps, seps)
        key = ordered[:, 0] * n + ordered[:, 1]
        rank = np.argsort(key)
        np.testing.assert_array_equal(ordered[rank], ref_pairs)
        np.testing.assert_allclose(signed[rank], ref_seps, rtol=0, atol=1e-12)
        outputs = []
        for shared in (True, False):
            vel, s_icep, s_dep, s_dep_stresslet = v.copy(), icep.copy(), dep.copy(), np.zeros((3, 3))
            if shared:
                add_pair_corrections(
                    pairs,
                    seps,
                    box,
                    e,
                    1.0,
                    1.0,
                    4.0,
                    0.5,
                    NEAR_FIELD_TABLES,
                    vel,
                    s_icep,
                    s_dep,
                    s_dep_stresslet,
                )
            else:
                add_near_field_corrections(
                    positions,
                    box,
                    offset,
                    e,
                    1.0,
                    1.0,
                    4.0,
                    0.5,
                    NEAR_FIELD_TABLES,
                    vel,
                    s_icep,
                    s_dep,
                    s_dep_stresslet,
                )
            outputs.append((vel, s_icep, s_dep, s_dep_stresslet))
        for got, expected in zip(outputs[0], outputs[1], strict=True):
            np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize(("icep_weight", "dep_weight"), [(1.0, 1.0), (1.0, 0.0), (0.0, 1.0)])
def test_accumulated_pair_stresses_equal_the_per_pair_sum(icep_weight: float, dep_weight: float) -> None:
    """The blend sums its stresslet corrections in the basis coefficients (A1, P, S2, M, R) and assembles the
    tensors once; the same sums pair by pair with the public ``add_basis`` (each pair's 3x3 tensors, as the
    blend did before 2026-12-06) agree to 1e-13 relative (rounding of two summation orders) over the ~900
    pairs of a random N = 64 packing, every mechanism switch; the velocities are unchanged by it."""
    from sim.dipolophoresis.near_field_blend import _pair_functions, add_pair_corrections, mechanism_codes
    from sim.dipolophoresis.near_field_stress import ICEP_PAIR_FAR_FIELD, add_basis
    from sim.geometry.configurations import random_packing
    from sim.geometry.neighbors import build_pair_list
    from sim.step_parameters import NEAR_FIELD_TABLES

    n = 64
    positions = random_packing(n, 0.45, 11, min_gap=1e-5)
    box = SimulationConfig(n_particles=n, volume_fraction=0.45).box_length
    pairs, seps = build_pair_list(positions, box, 0.0, 4.0)
    e = np.array([0.6, 0.8, 0.0])
    icep, virial, stresslet = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    add_pair_corrections(
        pairs, seps, box, e, icep_weight, dep_weight, 4.0, 0.5, NEAR_FIELD_TABLES,
        np.zeros((n, 3)), icep, virial, stresslet,
    )  # fmt: skip
    near_code, _ = mechanism_codes(icep_weight, dep_weight)
    ref_icep, ref_virial, ref_stresslet = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    volume = box**3
    for sep in seps:
        r = float(np.linalg.norm(sep))
        w = blend_weight(r, 4.0, 0.5)
        if w == 0.0:
            continue
        xh = -sep / r
        c = float(e @ xh)
        out = _pair_functions(r, near_code, icep_weight > 0, dep_weight > 0, NEAR_FIELD_TABLES)
        f1, f2, f3, f4, g1, g2, g3, g4, f_par, f_perp, f_x = out[3:]
        scale = math.pi * w / volume
        if icep_weight > 0:
            far = [v / r**3 for v in ICEP_PAIR_FAR_FIELD]
            add_basis(ref_icep, 2 * scale, f1 - far[0], f2 - far[1], f3 - far[2], f4 - far[3], xh, e)
        if dep_weight > 0:
            add_basis(ref_stresslet, 2 * scale, g1, g2, g3, g4, xh, e)
            force = (f_par * c * c + f_perp * (1 - c * c)) * xh + 2 * f_x * c * (e - c * xh)
            force_far = -3.0 * ((5 * c * c - 1) * xh - 2 * c * e) / r**4
            d = force - force_far
            ref_virial -= 0.5 * scale * r * (np.outer(xh, d) + np.outer(d, xh))
    for got, expected in ((icep, ref_icep), (virial, ref_virial), (stresslet, ref_stresslet)):
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-13 * max(np.abs(expected).max(), 1e-300))
    assert np.abs(ref_icep).max() + np.abs(ref_stresslet).max() > 0  # not trivially zero
    if dep_weight == 0:
        assert not virial.any() and not stresslet.any()
    if icep_weight == 0:
        assert not icep.any()
