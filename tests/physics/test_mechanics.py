"""The energy, its analytic gradient and Hessian, and its domain."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pneunet_env import ActuatorParams
from pneunet_env.physics import contact, mechanics
from pneunet_env.physics.mechanics import energy, energy_grad_hess, in_domain, kcot_half, scalar_terms, volume_change

# Points (kappa~, e_s, p~, k~_obj, w kappa_obj) spread over the domain: near kappa = 0, the series/direct switch
# of kappa cot(kappa/2), both sides of contact onset, the balloon region, and near the Gent limit.
POINTS = [
    (0.0, 0.0, 0.3, 0.0, 0.02),
    (1e-7, 1e-6, 0.3, 0.0, 0.02),
    (1e-3, 2e-3, 0.1, 1e-3, 0.02),
    (0.0999, 0.05, 0.5, 0.0, 0.02),
    (0.1001, 0.05, 0.5, 0.0, 0.02),
    (0.0199, 0.1, 0.4, 1e-2, 0.02),  # just out of contact
    (0.0201, 0.1, 0.4, 1e-2, 0.02),  # just in contact
    (0.0205, 0.3, 0.6, 1e-1, 0.02),  # very stiff object
    (0.3, 1.2, 0.8, 1e-4, 0.02),
    (0.55, 2.0, 1.2, 1e-5, 0.05),
    (2.0, 0.0, 0.2, 0.0, 0.02),  # strongly curled (e_m = 2)
]


def _near_gent(params: ActuatorParams, frac: float) -> tuple[float, float]:
    """A state whose side wall sits at I1 - 3 = frac * J."""
    J = params.gent_limit
    e = 0.0
    lo, hi = 0.0, 10.0
    for _ in range(200):
        e = 0.5 * (lo + hi)
        lo, hi = (e, hi) if mechanics.first_invariant(e) - 3.0 < frac * J else (lo, e)
    return 0.05, e


def _fd(params, k, s, p, kobj, ko, h):
    def g(kk, ss):
        return mechanics.gradient(kk, ss, p, params, kobj, ko)

    def u(kk, ss):
        return float(energy(kk, ss, p, params, kobj, ko))

    grad = np.array([(u(k + h, s) - u(k - h, s)) / (2 * h), (u(k, s + h) - u(k, s - h)) / (2 * h)])
    hess = np.column_stack([(g(k + h, s) - g(k - h, s)) / (2 * h), (g(k, s + h) - g(k, s - h)) / (2 * h)])
    return grad, hess


@pytest.mark.parametrize("point", POINTS)
def test_gradient_and_hessian_match_central_differences(params, point):
    k, s, p, kobj, ko = point
    # a step that stays inside kappa >= 0 and on one side of contact onset (where U'' jumps)
    h = float(np.clip(1e-4 * min(k, abs(k - ko)), 1e-9, 1e-6))
    if k - h < 0:
        k = h  # central differences need both sides
    d = energy_grad_hess(k, s, p, params, kobj, ko)
    grad, hess = _fd(params, k, s, p, kobj, ko, h)
    scale = 1.0 + np.abs(d.gradient).max()
    np.testing.assert_allclose(d.gradient, grad, rtol=0, atol=2e-7 * scale)
    np.testing.assert_allclose(d.hessian, hess, rtol=0, atol=2e-6 * (1.0 + np.abs(d.hessian).max()))
    assert d.hessian[0, 1] == d.hessian[1, 0]


@pytest.mark.parametrize("frac", [0.9, 0.99, 0.999])
def test_derivatives_near_the_gent_limit(params, frac):
    k, s = _near_gent(params, frac)
    d = energy_grad_hess(k, s, 0.5, params)
    grad, hess = _fd(params, k, s, 0.5, 0.0, 0.02, 1e-8)
    np.testing.assert_allclose(d.gradient, grad, rtol=1e-5)
    np.testing.assert_allclose(d.hessian, hess, rtol=1e-4)


def test_random_points_match_finite_differences():
    rng = np.random.default_rng(0)
    for _ in range(100):
        params = ActuatorParams(
            chamber_height=rng.uniform(0.6, 1.6),
            base_thickness=rng.uniform(0.2, 0.6),
            side_thickness=rng.uniform(0.2, 0.8),
            top_thickness=rng.uniform(0.2, 0.6),
            base_modulus=rng.uniform(10, 200),
            poisson_ratio=rng.uniform(0.0, 0.5),
            gent_limit=rng.uniform(5, 40),
        )
        k, s = rng.uniform(0.0, 0.8), rng.uniform(-0.2, 1.0)
        p, kobj, ko = rng.uniform(0, 2), 10 ** rng.uniform(-6, 0), rng.uniform(0.01, 0.1)
        if not in_domain(k, s, params) or k < 1e-5:
            continue
        d = energy_grad_hess(k, s, p, params, kobj, ko)
        grad, hess = _fd(params, k, s, p, kobj, ko, 1e-6)
        np.testing.assert_allclose(d.gradient, grad, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(d.hessian, hess, rtol=1e-5, atol=1e-5)


def test_scalar_kernel_equals_numpy_kernel(params):
    prm = params.as_tuple()
    for k, s, p, kobj, ko in POINTS:
        ok, U, gk, gs, hkk, hks, hss, dv, vk, vs = scalar_terms(k, s, p, *prm, kobj, ko)
        d = energy_grad_hess(k, s, p, params, kobj, ko)
        assert ok
        np.testing.assert_allclose([U, gk, gs, hkk, hks, hss], [d.energy, *d.gradient, *d.hessian.ravel()[[0, 1, 3]]],
                                   rtol=1e-14, atol=1e-15)


def test_rest_state_has_zero_energy_and_v1_equals_v0(params):
    for p in (0.0, 0.7, 3.0):
        assert energy(0.0, 0.0, p, params) == 0.0
    assert volume_change(0.0, 0.0, params) == 0.0
    g = mechanics.gradient(0.0, 0.0, 0.0, params)
    np.testing.assert_array_equal(g, [0.0, 0.0])
    other = ActuatorParams(chamber_height=1.4, side_thickness=0.3, top_thickness=0.6, base_thickness=0.2)
    assert abs(float(volume_change(0.0, 0.0, other))) < 1e-15


def test_kcot_is_exact_at_zero_and_continuous_across_the_series_switch():
    c, c1, c2 = kcot_half(0.0)
    assert (float(c), float(c1), float(c2)) == (2.0, 0.0, -1.0 / 3.0)
    r = mechanics.KCOT_SERIES_RADIUS
    below, above = kcot_half(r * (1 - 1e-12)), kcot_half(r * (1 + 1e-12))
    for a, b in zip(below, above, strict=True):
        assert abs(float(a) - float(b)) < 1e-13
    # against the direct formula, away from the switch
    k = 0.05
    assert abs(float(kcot_half(k)[0]) - k / math.tan(k / 2)) < 1e-15


@pytest.mark.parametrize(
    "k, s",
    [(-1e-3, 0.0), (math.pi, 0.0), (4.0, 0.1), (0.1, -1.0), (0.1, -1.5), (0.1, 5.0), (float("nan"), 0.0),
     (0.0, float("inf"))],
)
def test_energy_is_inf_outside_the_domain_never_nan(params, k, s):
    u = energy(k, s, 0.5, params, 1e-3, 0.02)
    assert u == math.inf
    assert not in_domain(k, s, params)
    # scalar kernel agrees and does not raise
    ok, U, *_ = scalar_terms(k, s, 0.5, *params.as_tuple(), 1e-3, 0.02)
    assert not ok and U == math.inf


def test_gent_limit_is_the_domain_edge(params):
    k, s = _near_gent(params, 0.999999)
    assert np.isfinite(energy(k, s, 0.0, params))
    assert energy(k, s * 1.01, 0.0, params) == math.inf


def test_vectorised_energy_broadcasts(params):
    k = np.linspace(0, 0.6, 7)
    s = np.linspace(0, 1.0, 7)
    d = energy_grad_hess(k, s, 0.5, params, np.full(7, 1e-3), 0.02)
    assert d.energy.shape == (7,) and d.gradient.shape == (7, 2) and d.hessian.shape == (7, 2, 2)
    for i in range(7):
        single = energy_grad_hess(k[i], s[i], 0.5, params, 1e-3, 0.02)
        np.testing.assert_allclose(d.hessian[i], single.hessian, rtol=1e-13)


def test_contact_force_and_indentation():
    assert contact.indentation(0.01, 0.02) == 0.0
    assert contact.contact(0.01, 1.0, 0.02)[1] == 0.0
    assert math.isclose(float(contact.indentation(0.025, 0.02)), 1 / 0.02 - 1 / 0.025)
    assert math.isclose(float(contact.contact(0.025, 1e-3, 0.02)[1]), 1e-3 * (50 - 40))
    assert contact.scalar_contact(0.025, 1e-3, 0.02) == (contact.scalar_indentation(0.025, 0.02),
                                                          1e-3 * contact.scalar_indentation(0.025, 0.02), True)
    assert contact.scalar_contact(0.025, 0.0, 0.02) == (0.0, 0.0, False)  # no object, no indentation
    # The object's energy has a continuous first derivative across contact onset (eq. 2.11), while its
    # second derivative jumps by k_obj / kappa_obj^4.
    p, kobj, ko, eps = ActuatorParams(), 1e-1, 0.02, 1e-13
    g_in = mechanics.gradient(ko + eps, 0.1, 0.4, p, kobj, ko)
    g_out = mechanics.gradient(ko - eps, 0.1, 0.4, p, kobj, ko)
    h_in = mechanics.hessian(ko + eps, 0.1, 0.4, p, kobj, ko)
    h_out = mechanics.hessian(ko - eps, 0.1, 0.4, p, kobj, ko)
    assert abs(g_in[0] - g_out[0]) < 3 * eps * kobj / ko**4
    assert math.isclose(h_in[0, 0] - h_out[0, 0], kobj / ko**4, rel_tol=1e-6)
