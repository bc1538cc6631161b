"""Cloth materials as data: named fabrics, what a user types, YAML files, the limits, and the
settings that carry a material (keys of datasets simulated before materials unchanged)."""

import pytest

from hrr_garment.errors import InputError
from hrr_garment.garment.fabrics import ABOUT, FABRICS, fabric
from hrr_garment.garment.material import LIMITS, Material, material_from, parse_material
from hrr_garment.sim.config import SimSettings


def test_every_named_fabric_is_a_valid_material_with_a_source():
    assert {"default", "denim", "jersey", "cotton-twill", "polyester"} <= set(FABRICS)
    for name, material in FABRICS.items():
        assert material.name == name
        assert ABOUT[name]
        for key, (low, high) in LIMITS.items():
            assert low <= getattr(material, key) <= high
    # the measured fabrics span a range worth conditioning on: 3x in weight, 6x in bending
    measured = [m for n, m in FABRICS.items() if n != "default"]
    assert max(m.density for m in measured) / min(m.density for m in measured) > 2.5
    assert max(m.bend for m in measured) / min(m.bend for m in measured) > 5


def test_what_a_user_types():
    assert parse_material("denim") == FABRICS["denim"]
    assert parse_material(" Denim ") == FABRICS["denim"]
    changed = parse_material("denim,bend=4e-6")
    assert changed.bend == 4e-6 and changed.density == FABRICS["denim"].density
    assert changed.name == "denim+bend"
    values = parse_material("density=0.2,stretch=5000")
    assert values.density == 0.2 and values.stretch == 5000 and values.bend == Material().bend


@pytest.mark.parametrize(
    ("spec", "words"),
    [
        ("velvet", "unknown fabric 'velvet'"),
        ("denim,bend=soft", "bend='soft' is not a number"),
        ("denim,colour=3", "unknown material value(s) colour"),
        ("density=-1", "density -1.0 kg/m^2 is outside"),
        ("density=nan", "density nan kg/m^2 is outside"),
        ("bend=1", "bend 1.0 N m is outside"),
        ("density=0.2,silk", "is neither a fabric"),
    ],
)
def test_bad_materials_are_refused_by_name(spec, words):
    with pytest.raises(InputError) as err:
        parse_material(spec, "--material")
    assert words in str(err.value) and str(err.value).startswith("--material: ")


def test_a_material_file(tmp_path):
    path = tmp_path / "my_silk.yaml"
    path.write_text("base: jersey\ndensity: 0.05\nbend: 2.0e-6\n")
    material = parse_material(str(path))
    assert material.name == "my_silk" and material.density == 0.05 and material.bend == 2e-6
    assert material.stretch == FABRICS["jersey"].stretch
    (tmp_path / "bad.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(InputError, match="bad.yaml: a material file is a mapping"):
        parse_material(str(tmp_path / "bad.yaml"))
    (tmp_path / "worse.yaml").write_text("density: [0.1\n")
    with pytest.raises(InputError, match="worse.yaml: is not valid YAML"):
        parse_material(str(tmp_path / "worse.yaml"))
    with pytest.raises(InputError, match="density: 'heavy' is not a number"):
        material_from({"density": "heavy"})


def test_settings_carry_a_material_and_keep_old_keys():
    plain = SimSettings()
    assert "material" not in plain.to_dict()  # datasets simulated before materials keep their keys
    silk = SimSettings.from_dict({"material": "polyester,bend=3e-6"})
    assert isinstance(silk.material, Material) and silk.material.bend == 3e-6
    again = SimSettings.from_dict(silk.to_dict())
    assert again == silk and again.to_dict() == silk.to_dict()
    # the ensemble's density perturbation reaches the material, not the unused raw density
    heavier = silk.with_density_scaled(1.0001)
    assert heavier.material.density == pytest.approx(silk.material.density * 1.0001)
    assert heavier.density == silk.density
    assert plain.with_density_scaled(2.0).density == 2 * plain.density
    with pytest.raises(InputError, match="simulator settings: material: unknown fabric 'velvet'"):
        SimSettings(material="velvet")
    assert fabric("JERSEY") is FABRICS["jersey"]
