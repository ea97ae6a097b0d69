"""Parameters are validated with errors that name the bad value; units convert both ways."""

from __future__ import annotations

import pytest

from pneunet_env import ActuatorParams
from pneunet_env.physics.units import (
    PAPER_MODULUS_PER_STIFFNESS_PA,
    PhysicalActuator,
    Scales,
    object_modulus_from_stiffness,
    object_stiffness_from_material,
)


def test_defaults_are_the_papers():
    p = ActuatorParams()
    assert p.as_tuple() == (1.0, 0.5, 0.5, 0.5, 60.0, 0.5, 20.0)
    assert ActuatorParams(gent_limit=15.0).gent_limit == 15.0


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"base_modulus": -60.0}, "base_modulus"),
        ({"base_modulus": 0.0}, "base_modulus"),
        ({"side_thickness": 1.2}, "side_thickness"),  # side wall thicker than the chamber's width
        ({"top_thickness": 1.5, "base_thickness": 0.6}, "top_thickness"),  # walls thicker than the chamber's height
        ({"top_thickness": -0.5}, "top_thickness"),
        ({"chamber_height": 0.0}, "chamber_height"),
        ({"gent_limit": 0.0}, "gent_limit"),
        ({"gent_limit": -3.0}, "gent_limit"),
        ({"poisson_ratio": 0.6}, "poisson_ratio"),
        ({"poisson_ratio": -1.0}, "poisson_ratio"),
        ({"gent_limit": float("nan")}, "gent_limit"),
        ({"base_modulus": "stiff"}, "base_modulus"),
    ],
)
def test_invalid_parameters_raise_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ActuatorParams(**kwargs)


def test_replace_validates_and_rejects_unknown_fields():
    assert ActuatorParams().replace(gent_limit=10.0).gent_limit == 10.0
    with pytest.raises(ValueError, match="gent_limt"):
        ActuatorParams().replace(gent_limt=10.0)
    with pytest.raises(ValueError, match="gent_limit"):
        ActuatorParams().replace(gent_limit=-1.0)


def test_eq_3_3_modulus_per_stiffness_is_about_1_5e7_pa():
    assert PAPER_MODULUS_PER_STIFFNESS_PA == pytest.approx(1.5e7, rel=0.03)
    # 15 kPa elastomer is stiff (k~ > 1e-3); 1.5 kPa gel is soft (k~ < 1e-4)  (section 3)
    assert object_stiffness_from_material(15.0, 10.0, 4.0) > 1e-3
    assert object_stiffness_from_material(1.5, 10.0, 4.0) < 1.1e-4


def test_object_stiffness_round_trip_and_errors():
    k = object_stiffness_from_material(7.0, 10.0, 4.0)
    assert object_modulus_from_stiffness(k, 10.0, 4.0) == pytest.approx(7.0, rel=1e-12)
    with pytest.raises(ValueError, match="shear_modulus_kpa"):
        object_stiffness_from_material(-1.0, 10.0, 4.0)
    with pytest.raises(ValueError, match="thickness"):
        object_stiffness_from_material(1.0, 300.0, 4.0)  # thicker than its radius
    with pytest.raises(ValueError, match="stiffness"):
        object_modulus_from_stiffness(-1e-3, 10.0, 4.0)


def test_table1_physical_actuator_round_trip():
    phys = PhysicalActuator()
    dimless = phys.to_dimensionless()
    assert dimless == ActuatorParams()
    assert PhysicalActuator.from_dimensionless(dimless, phys.scales) == phys
    with pytest.raises(ValueError, match="side_thickness"):
        PhysicalActuator(side_thickness_mm=6.0).to_dimensionless()
    with pytest.raises(ValueError, match="shear_modulus_kpa"):
        PhysicalActuator(shear_modulus_kpa=-50.0)


def test_scales_validate():
    assert Scales() == Scales(width_mm=5.0, shear_modulus_kpa=50.0)
    with pytest.raises(ValueError, match="width_mm"):
        Scales(width_mm=0.0)


@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf"), "x"])
def test_check_positive_names_the_bad_value(value):
    from pneunet_env.physics.params import check_positive

    with pytest.raises(ValueError, match="jaw_step_mm"):
        check_positive("jaw_step_mm", value)
    assert check_positive("jaw_step_mm", 2) == 2.0
