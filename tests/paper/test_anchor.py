"""The experimental anchor (pneunet_env.paper.anchor): its blocked moment is the model's own, its table is the docs'."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from pneunet_env.paper import anchor
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import evaluate_state, params_tuple, solve_equilibrium

DOCS = Path(__file__).resolve().parents[2] / "docs" / "physics.md"


@pytest.mark.parametrize("pressure", [1e-3, 2e-3])
def test_the_straight_moment_bends_the_free_finger_as_the_solver_does(pressure):
    # at a small pressure the free finger's curvature is the straight finger's moment over its relaxed bending
    # stiffness (h_kk - h_ks^2 / h_ss): the moment's sign and scale are the energy's, checked against the solver
    params = ActuatorParams()
    prm = params_tuple(params)
    m = anchor.straight_moment(pressure, prm)
    free = solve_equilibrium(pressure, 0.0, 0.02, params)
    strain = anchor._downhill_strain(0.0, 0.0, pressure, prm)
    ev = evaluate_state(0.0, strain, pressure, prm, 0.0, 1.0)
    stiffness = ev.h_kk - ev.h_ks ** 2 / ev.h_ss
    assert m > 0 and abs(ev.g_strain) < 1e-8 and ev.h_ss > 0
    assert m / stiffness == pytest.approx(free.curvature, rel=20 * pressure)


def test_a_point_maps_the_measured_actuator_and_its_units():
    act = anchor.anchor_actuator(10.0, 2.0, 40.0, 20.0)
    assert act.finger_width_mm == anchor.WIDTH_MM and act.length_mm == anchor.LENGTH_MM
    assert act.base_thickness_mm / 2 + act.chamber_height_mm + act.top_thickness_mm / 2 == anchor.THICKNESS_MM
    pt = anchor.anchor_point(10.0, 2.0, 40.0, 20.0)
    assert pt.converged and math.isfinite(pt.tip_force_n) and pt.tip_force_n > 0
    # N: mu (kPa) t w^2 (mm^3) M~ 1e-3 / L (mm)
    m = anchor.straight_moment(anchor.PRESSURE_KPA / 40.0, params_tuple(act.to_dimensionless()))
    assert pt.tip_force_n == pytest.approx(40.0 * act.depth_mm * 100.0 * m * 1e-3 / anchor.LENGTH_MM, rel=1e-12)
    assert pt.force_ratio == pytest.approx(pt.tip_force_n / 0.34)


def test_the_docs_show_the_sweep_as_it_runs_now():
    table = anchor.render(anchor.summary(anchor.sweep()))
    assert table in DOCS.read_text(encoding="utf-8"), table
