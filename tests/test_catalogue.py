"""The real-object catalogue (``pneunet_env/data/objects.yaml``) and its loader (``pneunet_env.catalogue``).

* every packaged class is complete and valid (ranges, sources, ``H < R``, the ``H`` rule of the file's header);
* the use cases weight only known classes inside the annulus model, and the default one exists;
* malformed files raise ``ValueError`` naming the class (or use case) and the field;
* nothing is printed.
"""

from __future__ import annotations

import copy
import math
from importlib import resources

import pytest
import yaml

from pneunet_env.catalogue import (
    RANGE_FIELDS,
    ObjectClass,
    default_use_case,
    load_catalogue,
    load_use_cases,
    stiffness_range,
    use_case_weights,
)
from pneunet_env.physics.contact import winkler_stiffness

CATALOGUE = load_catalogue()

# The material classes the catalogue must cover (hydrogels, phantoms, elastomers, rubber, soft food, fruit).
REQUIRED_CLASSES = (
    "gelatin_gel",
    "agar_gel",
    "pva_cryogel",
    "soft_silicone",
    "firm_silicone",
    "natural_rubber",
    "soft_cheese",
    "apple",
    "kiwifruit",
)
REACH_RADIUS_MM = 9.4  # the free actuator reaches w kappa <= 0.53 with w = 5 mm


# ---------------------------------------------------------------------------------------------
# The packaged catalogue
# ---------------------------------------------------------------------------------------------


def test_the_yaml_is_package_data():
    res = resources.files("pneunet_env.data").joinpath("objects.yaml")
    assert res.is_file()
    assert yaml.safe_load(res.read_text(encoding="utf-8"))["classes"]


def test_required_classes_and_an_out_of_model_class_are_present():
    assert set(REQUIRED_CLASSES) <= set(CATALOGUE)
    assert any(not c.in_annulus_model for c in CATALOGUE.values()), "no class outside eq. 3.2 (foams, sponges)"


@pytest.mark.parametrize("name", list(CATALOGUE))
def test_every_row_is_complete_and_valid(name):
    c = CATALOGUE[name]
    assert isinstance(c, ObjectClass) and c.name == name
    assert c.description and c.reason
    for field in (*RANGE_FIELDS, "shear_modulus_kpa"):
        low, high = getattr(c, field)
        assert math.isfinite(low) and math.isfinite(high), field
        assert 0.0 < low <= high, field
    assert c.shear_modulus_kpa == pytest.approx((c.youngs_modulus_kpa[0] / 3, c.youngs_modulus_kpa[1] / 3))
    assert c.sources and all(isinstance(s, str) and s.strip() for s in c.sources)
    assert c.thickness_mm[1] < c.radius_mm[0], "H must stay below R at every corner (H kappa_obj < 1)"
    assert isinstance(c.in_annulus_model, bool)


@pytest.mark.parametrize("name", list(CATALOGUE))
def test_thickness_follows_the_stated_rule(name):
    # H_hi = min(10 mm, R_lo/2), H_lo = H_hi/2 (rounded to 0.1 mm at most).
    c = CATALOGUE[name]
    h_hi = min(10.0, c.radius_mm[0] / 2)
    assert c.thickness_mm[1] == pytest.approx(h_hi, abs=0.06)
    assert c.thickness_mm[0] == pytest.approx(c.thickness_mm[1] / 2, abs=0.06)


@pytest.mark.parametrize("name", [n for n, c in CATALOGUE.items() if c.in_annulus_model])
def test_classes_in_the_model_are_within_the_actuators_reach(name):
    assert CATALOGUE[name].radius_mm[0] >= REACH_RADIUS_MM


def test_bread_is_in_the_catalogue_with_sources_and_out_of_the_model():
    # issue #12: bread crumb is a cellular solid (>70 % gas): listed with its literature values, never drawn
    bread = CATALOGUE["bread"]
    assert not bread.in_annulus_model
    assert "gas" in bread.reason
    tags = " ".join(s.split("]")[0] for s in bread.sources)
    for field in ("E", "failure stress", "density"):
        assert field in tags, field
    assert any("doi:10.1006/jcrs.2000.0334" in s for s in bread.sources)  # Sapirstein, Fahloul, Scanlon (2000)
    # more than half gas by rule 1 of docs/env.md, even if the cell walls were no denser than water
    assert bread.density_kg_m3[1] < 0.5 * 998.0
    # failure strain DERIVED with the linear rule sigma_f = E eps_f at the ends of the ranges
    lo = bread.failure_stress_kpa[0] / bread.youngs_modulus_kpa[1]
    hi = bread.failure_stress_kpa[1] / bread.youngs_modulus_kpa[0]
    assert bread.failure_strain == pytest.approx((lo, hi), rel=0.03)
    cases = load_use_cases()
    for name in ("kitchen", "catalogue_uniform"):
        assert "bread" in cases[name].unreachable and "bread" not in cases[name].weights, name


def test_apple_holds_flesh_specimen_values_not_the_apparent_whole_fruit_modulus():
    # the modulus field is the flesh's Young's modulus from excised specimens (Chakespari et al. 2010: 0.81 MPa
    # initial tangent; Shahabasi 1979: up to 3.28 MPa, Jonathan), not ASAE S368's apparent modulus of a die pressed
    # into the whole fruit (Vursavus et al. 1999: up to 4.88 MPa), which is listed as not used
    apple = CATALOGUE["apple"]
    assert apple.youngs_modulus_kpa == pytest.approx((810.0, 3280.0))
    assert apple.failure_strain == pytest.approx((0.11, 0.312))  # flesh specimens in compression, both studies
    assert apple.failure_stress_kpa == pytest.approx((235.0, 444.0))
    used = [s for s in apple.sources if not s.startswith("[not used")]
    assert any("Shahabasi" in s for s in used) and any("Chakespari" in s for s in used)
    assert not any("Vursavus" in s or "Turkish Journal" in s for s in used)


def test_pva_failure_is_measured_on_a_phantom_cryogel():
    # Mori, Tokura and Yoshikawa (1997): 8.6 wt% PVA, two freeze-thaw cycles, 0.6 MPa and 130 % in tension; the
    # former 3-12 (derived from anisotropic tough gels) is gone
    pva = CATALOGUE["pva_cryogel"]
    assert pva.failure_strain[0] <= 1.3 <= pva.failure_strain[1] and pva.failure_strain[1] < 2.0
    assert pva.failure_stress_kpa[0] <= 600.0 <= pva.failure_stress_kpa[1]
    assert any("doi:10.1023/A:1018586307534" in s for s in pva.sources)
    assert not any("c2sm26102b" in s for s in pva.sources)


def test_kitchen_weights_are_the_ones_fixed_before_any_result():
    # the default use case's weights were fixed before any success rate was computed (docs/env.md): adding a class
    # to the catalogue never changes them
    assert use_case_weights("kitchen") == pytest.approx(
        {"apple": 0.30, "kiwifruit": 0.25, "soft_cheese": 0.25, "gelatin_gel": 0.20})
    assert set(load_use_cases()["catalogue_uniform"].weights) == {n for n, c in CATALOGUE.items() if c.in_annulus_model}


# ---------------------------------------------------------------------------------------------
# Use cases
# ---------------------------------------------------------------------------------------------


def test_default_use_case_weights_name_only_known_classes_inside_the_model():
    weights = use_case_weights()
    assert weights and set(weights) <= set(CATALOGUE)
    assert all(w >= 0 for w in weights.values())
    assert sum(weights.values()) == pytest.approx(1.0)
    assert all(CATALOGUE[n].in_annulus_model for n, w in weights.items() if w > 0)
    assert weights == use_case_weights(default_use_case())


def test_every_use_case_is_valid_and_there_is_an_alternative():
    cases = load_use_cases()
    assert default_use_case() in cases and len(cases) >= 2
    for name, case in cases.items():
        assert case.description and case.reason, name
        assert set(case.weights) <= set(CATALOGUE), name
        assert all(not CATALOGUE[c].in_annulus_model for c in case.unreachable), name
        assert sum(use_case_weights(name).values()) == pytest.approx(1.0)


def test_unknown_use_case_is_a_key_error():
    with pytest.raises(KeyError, match="no_such_case"):
        use_case_weights("no_such_case")


# ---------------------------------------------------------------------------------------------
# stiffness_range
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(CATALOGUE))
def test_stiffness_range_spans_the_corners(name):
    c = CATALOGUE[name]
    lo, hi = stiffness_range(c)
    assert 0.0 < lo <= hi
    # k~ grows with mu and H and falls with R: the extremes are (mu_lo, R_hi, H_lo) and (mu_hi, R_lo, H_hi).
    soft = winkler_stiffness(c.shear_modulus_kpa[0], c.thickness_mm[0], 1e3 / c.radius_mm[1], 5.0, 50.0)
    stiff = winkler_stiffness(c.shear_modulus_kpa[1], c.thickness_mm[1], 1e3 / c.radius_mm[0], 5.0, 50.0)
    assert (lo, hi) == pytest.approx((soft, stiff))
    # the scales enter linearly: k~ = k_obj w / mu
    lo2, hi2 = stiffness_range(c, width_mm=10.0, scale_modulus_kpa=100.0)
    assert (lo2, hi2) == pytest.approx((lo, hi))


# ---------------------------------------------------------------------------------------------
# Validation of malformed files
# ---------------------------------------------------------------------------------------------

_GOOD_CLASS = {
    "description": "a test gel",
    "youngs_modulus_kpa": [3.0, 30.0],
    "density_kg_m3": [1000.0, 1050.0],
    "failure_strain": [0.2, 0.4],
    "failure_stress_kpa": [1.0, 10.0],
    "radius_mm": [15.0, 40.0],
    "thickness_mm": [3.75, 7.5],
    "in_annulus_model": True,
    "reason": "solid gel",
    "sources": ["Somebody (2020) A paper. doi:10.0/x"],
}
_GOOD_FOAM = {**_GOOD_CLASS, "description": "a test foam", "in_annulus_model": False, "reason": "a foam"}
_GOOD = {
    "schema_version": 1,
    "classes": {"test_gel": _GOOD_CLASS, "test_foam": _GOOD_FOAM},
    "use_cases": {
        "default": "bench",
        "bench": {"description": "d", "reason": "r", "weights": {"test_gel": 1.0}, "unreachable": ["test_foam"]},
    },
}


def _write(tmp_path, doc):
    path = tmp_path / "objects.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    return path


def _bad(mutate):
    doc = copy.deepcopy(_GOOD)
    mutate(doc)
    return doc


def test_the_minimal_good_file_loads(tmp_path):
    path = _write(tmp_path, _GOOD)
    assert set(load_catalogue(path)) == {"test_gel", "test_foam"}
    assert use_case_weights(path=path) == {"test_gel": 1.0}


_CLS = "test_gel"


def _set(field, value, cls=_CLS):
    def mutate(doc):
        doc["classes"][cls][field] = value

    return mutate


def _drop(field, cls=_CLS):
    def mutate(doc):
        del doc["classes"][cls][field]

    return mutate


def _weights(weights, unreachable=("test_foam",)):
    def mutate(doc):
        doc["use_cases"]["bench"]["weights"] = weights
        doc["use_cases"]["bench"]["unreachable"] = list(unreachable)

    return mutate


BAD_ROWS = {
    # kind: (mutation, words the message must contain)
    "missing range field": (_drop("radius_mm"), ["test_gel", "radius_mm", "missing"]),
    "missing failure field": (_drop("failure_stress_kpa"), ["test_gel", "failure_stress_kpa", "missing"]),
    "missing boolean": (_drop("in_annulus_model"), ["test_gel", "in_annulus_model", "missing"]),
    "missing reason": (_drop("reason"), ["test_gel", "reason", "missing"]),
    "null range": (_set("density_kg_m3", None), ["test_gel", "density_kg_m3", "missing"]),
    "low > high": (_set("youngs_modulus_kpa", [30.0, 3.0]), ["test_gel", "youngs_modulus_kpa", "low > high"]),
    "zero value": (_set("failure_strain", [0.0, 0.4]), ["test_gel", "failure_strain", "positive"]),
    "negative value": (_set("density_kg_m3", [-1.0, 1000.0]), ["test_gel", "density_kg_m3", "positive"]),
    "not a pair": (_set("radius_mm", [15.0]), ["test_gel", "radius_mm", "[low, high]"]),
    "not numbers": (_set("radius_mm", ["a", "b"]), ["test_gel", "radius_mm", "[low, high]"]),
    "blank source": (_set("sources", ["  "]), ["test_gel", "sources"]),
    "H >= radius": (_set("thickness_mm", [5.0, 15.0]), ["test_gel", "thickness_mm", "radius"]),
    "non-boolean in_annulus_model": (_set("in_annulus_model", "yes"), ["test_gel", "in_annulus_model"]),
    "unknown class in use case": (_weights({"test_gel": 1.0, "tofu": 1.0}), ["bench", "tofu", "unknown"]),
    "negative weight": (_weights({"test_gel": -1.0}), ["bench", "test_gel", "negative"]),
    "weights summing to zero": (_weights({"test_gel": 0.0}), ["bench", "sum to a positive"]),
    "non-numeric weight": (_weights({"test_gel": "lots"}), ["bench", "test_gel", "number"]),
    "out-of-model class weighted": (
        _weights({"test_gel": 1.0, "test_foam": 1.0}, unreachable=()),
        ["bench", "test_foam", "outside the annulus model"],
    ),
    "in-model class listed unreachable": (
        _weights({"test_gel": 1.0}, unreachable=("test_foam", "test_gel")),
        ["bench", "test_gel", "unreachable"],
    ),
    "unknown default": (lambda doc: doc["use_cases"].update(default="garden"), ["default", "garden"]),
}


@pytest.mark.parametrize("kind", list(BAD_ROWS))
def test_bad_rows_raise_value_error_naming_class_and_field(tmp_path, kind):
    mutate, words = BAD_ROWS[kind]
    path = _write(tmp_path, _bad(mutate))
    with pytest.raises(ValueError) as info:
        load_catalogue(path)
    message = str(info.value)
    for word in words:
        assert word in message, (kind, message)


def test_not_a_mapping_or_not_yaml(tmp_path):
    path = tmp_path / "objects.yaml"
    path.write_text("- just\n- a list\n", encoding="utf-8")
    with pytest.raises(ValueError, match="mapping"):
        load_catalogue(path)
    path.write_text("classes: [unclosed\n", encoding="utf-8")
    with pytest.raises(ValueError, match="YAML"):
        load_catalogue(path)


@pytest.mark.parametrize("mutate", [_drop("sources"), _set("sources", [])], ids=["missing", "empty"])
def test_a_users_class_without_sources_is_read_as_unsourced_and_a_packaged_one_is_refused(tmp_path, mutate):
    """A user's catalogue (``--catalogue PATH``) may lack sources: the class is read with ``sources == ()``, which the
    outputs report as UNSOURCED; the packaged file's rule (every class sourced) is unchanged."""
    from pneunet_env.catalogue import _classes
    from pneunet_env.yamlio import load_yaml_file

    path = _write(tmp_path, _bad(mutate))
    assert load_catalogue(path)["test_gel"].sources == ()
    with pytest.raises(ValueError, match="test_gel.*sources"):
        _classes(load_yaml_file(path, "catalogue file"), "packaged")


def test_nothing_is_printed(capsys, tmp_path):
    load_catalogue()
    load_use_cases()
    use_case_weights()
    for c in CATALOGUE.values():
        stiffness_range(c)
    with pytest.raises(ValueError):
        load_catalogue(_write(tmp_path, _bad(_set("sources", ["  "]))))
    out, err = capsys.readouterr()
    assert out == "" and err == ""


def test_a_duplicated_class_or_field_is_refused_naming_it_and_its_line(tmp_path):
    """Before: PyYAML kept the second entry of a duplicated class name, silently."""
    import json

    text = yaml.safe_dump(json.loads(json.dumps(_GOOD)), sort_keys=False)  # no shared lists: no anchors
    first = text.index("  test_gel:")
    block = text[first:text.index("  test_foam:")]
    path = tmp_path / "objects.yaml"
    path.write_text(text.replace(block, block + block.replace("a test gel", "a second gel")), encoding="utf-8")
    with pytest.raises(ValueError, match=r"objects\.yaml', line \d+, column \d+: duplicate key 'test_gel' \(first at"):
        load_catalogue(path)
    path.write_text(text.replace("  test_gel:\n", "  test_gel:\n    in_annulus_model: false\n", 1), encoding="utf-8")
    with pytest.raises(ValueError, match="duplicate key 'in_annulus_model'"):
        load_catalogue(path)


def test_catalogue_numbers_read_as_in_every_other_file(tmp_path):
    """``3e3`` is a number here as in an env config (PyYAML alone read it as a string, refused as 'not numbers')."""
    doc = copy.deepcopy(_GOOD)
    path = tmp_path / "objects.yaml"
    text = yaml.safe_dump(doc, sort_keys=False).replace("- 3.75\n", "- 3.75e0\n")
    path.write_text(text, encoding="utf-8")
    assert load_catalogue(path)["test_gel"].thickness_mm[0] == 3.75


def test_use_case_weights_that_overflow_are_refused(tmp_path):
    path = _write(tmp_path, _bad(_weights({"test_gel": 1e308, "test_foam": 0.0}, unreachable=())))
    assert load_catalogue(path)  # one huge weight is fine
    doc = _bad(_weights({"test_gel": 1e308}))
    doc["classes"]["test_gel2"] = dict(_GOOD_CLASS)
    doc["use_cases"]["bench"]["weights"]["test_gel2"] = 1e308
    with pytest.raises(ValueError, match="'bench': the weights sum past the largest float"):
        load_catalogue(_write(tmp_path, doc))


def test_a_missing_catalogue_file_is_a_named_value_error(tmp_path):
    with pytest.raises(ValueError, match=r"cannot read catalogue file '.*nowhere\.yaml'"):
        load_catalogue(tmp_path / "nowhere.yaml")
