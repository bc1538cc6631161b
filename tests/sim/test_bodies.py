"""Which bodies a build simulates on: the preset's bodies section checked, sampled bodies spread over
the statures asked for, every clip on its bodies, presets that extend another."""

import pytest

from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.errors import InputError
from hrr_garment.garment.templates import make_garment
from hrr_garment.sim.bodies import BodyPlan, plan_bodies
from hrr_garment.sim.plan import SequenceSpec, load_preset


@pytest.mark.parametrize("section, phrase", [({"from": "nowhere"}, "'from' must be"), ({"from": "sample", "colour": 1}, "colour"),
                                             ({"from": "sample", "count": 4, "per_clip": 5}, "per_clip"),
                                             ({"from": "sample", "statures_m": [1.9, 1.5]}, "low first")])
def test_a_bad_bodies_section_is_refused_naming_the_preset(section, phrase):
    with pytest.raises(InputError, match=phrase) as err:
        BodyPlan.from_preset(section, "my-preset.yaml")
    assert "my-preset.yaml" in str(err.value)


def test_no_bodies_section_is_the_mannequin():
    assert BodyPlan.from_preset({}, "p") is None


def test_sampled_bodies_span_the_statures_and_share_the_clips():
    pytest.importorskip("anny", reason="the bodies extra is not installed")
    plan = BodyPlan("sample", count=3, per_clip=2, statures_m=(1.5, 1.9))
    specs = [SequenceSpec(f"walk_{i:03d}", "walk", seed=i, seconds=1.0) for i in range(3)]
    planned, bodies = plan_bodies(plan, specs, make_garment("skirt", 200), made_for=DEFAULT_BODY,
                                  progress=False)
    statures = sorted(b.record.stature for b in bodies.values())
    assert statures == pytest.approx([1.5, 1.7, 1.9], abs=0.005)
    assert len(planned) == 6 and len({s.name for s in planned}) == 6
    for spec in specs:  # each clip on two different bodies
        mine = [s.body for s in planned if s.name.startswith(spec.name + "__")]
        assert len(set(mine)) == 2
    assert sorted(s.body for s in planned) == sorted(list(bodies) * 2)  # every body gets its share
    assert {s.shape["gender"] for s in (b.record for b in bodies.values())} == {0.0, 1.0}


def test_a_preset_extends_another_and_replaces_only_what_it_names():
    base, bodies = load_preset("real-quick"), load_preset("real-quick-bodies")
    assert bodies.name == "real-quick-bodies" and bodies.bodies["from"] == "sample"
    assert (bodies.motions, bodies.sim, bodies.sequences, bodies.mirror) == (base.motions, base.sim, base.sequences, base.mirror)
    assert load_preset("real-quick-performers").bodies == {"from": "performer"}
