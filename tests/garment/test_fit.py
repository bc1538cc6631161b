"""Your own garment: fitting a mesh authored in another convention, finding its attached vertices,
refusing bad or far too dense meshes, and the whole way through simulate, train and animate."""

import argparse

import numpy as np
import pytest

from hrr_garment.garment.fit import _rotation_to_y, auto_attached, fit_garment, hem_loop, hem_up_axis
from hrr_garment.garment.mesh import GarmentError
from hrr_garment.garment.obj import write_obj
from hrr_garment.garment.templates import make_garment
from tests.conftest import authored


@pytest.mark.parametrize(
    "name, convert, unit, up",
    [
        ("dress", authored, "cm", "+z"),
        ("skirt", lambda v: v * 1000.0, "mm", "+y"),  # millimetres, already standing on the ground
        # lying along -x (turned so that the fit's rotation undoes it: front and back cannot be told apart)
        ("dress", lambda v: v @ _rotation_to_y(0, -1.0), "m", "-x"),
    ],
)
def test_a_garment_in_another_convention_lands_where_the_template_is(name, convert, unit, up):
    garment = make_garment(name, 400)
    fit = fit_garment(convert(garment.vertices), garment.faces)
    assert (fit.unit, fit.up) == (unit, up)
    assert np.linalg.det(fit.rotation) == pytest.approx(1.0)
    assert (
        np.abs(fit.apply(convert(garment.vertices)) - garment.vertices).max() < 0.012
    )  # metres: within a centimetre
    assert "unit " + unit in fit.describe()


def test_up_axis_comes_from_the_hem_and_can_be_given():
    garment = make_garment("skirt", 400)  # wider than it is tall: the longest extent is not up
    assert np.ptp(garment.vertices[:, 2]) > np.ptp(garment.vertices[:, 1])
    assert hem_up_axis(garment.vertices, garment.faces) == (1, 1.0)
    flipped = fit_garment(garment.vertices * [1, -1, -1], garment.faces, up="-y")
    assert (
        flipped.up == "-y"
        and np.abs(flipped.apply(garment.vertices * [1, -1, -1]) - garment.vertices).max() < 0.005
    )
    with pytest.raises(GarmentError, match="cannot tell the unit"):
        fit_garment(garment.vertices * 1e5, garment.faces)
    closed = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]])
    with pytest.raises(GarmentError, match="no open boundary"):
        fit_garment(np.array([[0, 0, 0], [0.5, 0, 0], [0, 0.5, 0], [0, 0, 0.5]]), closed)


@pytest.mark.parametrize("name", ["dress", "skirt", "pleated_skirt", "asymmetric_skirt"])
def test_the_hem_is_the_longest_open_boundary(name):
    garment = make_garment(name, 500)
    assert np.array_equal(hem_loop(garment.vertices, garment.faces), np.sort(garment.groups["hem"]))


def test_auto_attached_is_the_top_band_on_the_torso():
    skirt = make_garment("skirt", 400)
    assert np.array_equal(np.sort(auto_attached(skirt.vertices)), np.sort(skirt.attached))  # the waistband
    dress = make_garment("dress", 400)
    found = auto_attached(dress.vertices)
    assert set(found) <= set(dress.groups["straps"]) and set(found) >= set(
        dress.groups["shoulders"]
    )  # strap tops
    with pytest.raises(GarmentError, match="lies within 2 cm of the torso"):
        auto_attached(dress.vertices + [0.0, 0.0, 0.5])  # half a metre in front of the body


def test_a_far_too_dense_template_is_refused_with_a_way_forward(tmp_path, capsys):
    from hrr_garment.cli.garment_options import resolve_garment
    from hrr_garment.cli.simulate import main as simulate_main

    dense = make_garment("dress", 1200)
    path = tmp_path / "dense.obj"
    write_obj(path, authored(dense.vertices), dense.faces)
    out = tmp_path / "never.h5"
    assert (
        simulate_main(
            ["--template", str(path), "--fit", "--attached", "auto", "--preset", "tiny", "-o", str(out)]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "dense.obj" in err and "far more than this preset's 300" in err and "--dense-ok" in err
    assert not out.exists()
    args = argparse.Namespace(
        template=path,
        garment=None,
        attached="auto",
        attached_file=None,
        fit=True,
        up=None,
        unit=None,
        dense_ok=True,
    )
    assert resolve_garment(args, 300).num_vertices == dense.num_vertices
    assert simulate_main(["--garment", "dress", "--fit", "-o", str(out)]) == 2
    assert "use it with --template" in capsys.readouterr().err


def test_an_artist_dress_goes_through_simulate_train_and_animate(artist_model, tmp_path):
    """No groups, centimetres, Z up, pelvis at the origin: --fit --attached auto, a tiny simulation,
    a tiny model (conftest's ``artist_model``), an animation."""
    from hrr_garment.cli.animate import main as animate_main
    from hrr_garment.data.animation_file import read_animation_h5
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.inference.animator import Animator
    from hrr_garment.motion.io import save_motion
    from hrr_garment.motion.synth import synthesize

    data, model, out = artist_model
    dress = make_garment("dress", 300)
    assert "fitted artist_dress.obj: unit cm (x0.01), up axis +z -> +y" in out and "attached (auto):" in out
    ds = GarmentDataset(data)
    assert np.abs(ds.template.vertices - dress.vertices).max() < 0.005 and len(ds.template.attached) > 0
    assert data.with_suffix(".preview.png").is_file()
    dance = synthesize("dance", 1.0, seed=9)
    save_motion(dance, tmp_path / "dance.npz")
    assert (
        animate_main([str(tmp_path / "dance.npz"), "--model", str(model), "-o", str(tmp_path / "out.h5")])
        == 0
    )
    anim = read_animation_h5(tmp_path / "out.h5")
    assert anim.vertices.shape == (30, dress.num_vertices, 3) and np.isfinite(anim.vertices).all()
    # trained as bundles were before the motion memory and the expected code: the 124 plain features
    # and the argmax regression end to end
    animator = Animator.load(model)
    config = animator.bundle.codespace.config
    assert (
        animator.bundle.codespace.features == 124
        and config.memory_seconds == () == config.resonator_hz
        and config.regression_code == "argmax"
    )
    stream = animator.stream()
    streamed = np.stack([stream.push(dance.slice(t, t + 1)) for t in range(5)])
    np.testing.assert_allclose(streamed, animator.animate(dance.slice(0, 5), causal=True).vertices, atol=1e-5)


def test_fit_says_how_much_of_a_garment_for_another_body_lands_inside_and_points_to_made_for():
    from tests.garment.test_templates_on_bodies import _larger_body

    own = fit_garment(make_garment("dress", 400).vertices, make_garment("dress", 400).faces)
    assert own.inside == 0.0 and "--made-for" not in own.describe()
    slim = make_garment("dress", 400, body=_larger_body(0.95, 0.7))  # modelled on a slimmer body
    fit = fit_garment(slim.vertices, slim.faces)
    assert fit.inside > 0.01
    assert f"{100 * fit.inside:.1f} % of its vertices land more than 5 mm inside" in fit.describe()
    assert "--made-for" in fit.describe()
