"""hrr-animate: out.h5 and its attributes, bad motion, bad models and outputs explained."""

import json

import numpy as np

from hrr_garment.motion.synth import synthesize


def test_hrr_animate_writes_out_h5_and_refuses_bad_motion(trained, tmp_path, capsys, monkeypatch):
    from hrr_garment.cli.animate import main as animate_main
    from hrr_garment.data.animation_file import read_animation_h5
    from hrr_garment.motion.io import save_motion
    from hrr_garment.native import load_kernel

    root, _, _ = trained
    clip = tmp_path / "walk.npz"
    save_motion(synthesize("walk", 1.0, seed=4), clip)
    out = tmp_path / "out.h5"
    assert animate_main([str(clip), "-o", str(out), "--model", str(root / "model")]) == 0
    said = capsys.readouterr().out
    auto = json.loads((root / "model" / "bundle.json").read_text())["auto"][
        "mode"
    ]  # the default mode runs it
    assert f"mode auto = {auto}" in said
    assert (
        "a database match on every frame" if auto in ("residual", "detail") else "retrieval usage"
    ) in said
    data = read_animation_h5(out)
    assert data.vertices.shape == (30, 308, 3) and data.faces.dtype == np.int32
    assert data.joints.shape == (30, 22, 3) and data.retrieved.dtype == np.uint8
    assert data.capsules.shape == (30, len(data.radii), 2, 3)
    attrs = data.attrs
    assert (
        attrs["fps"] == 30
        and attrs["units"] == "m"
        and attrs["up_axis"] == "Y"
        and attrs["garment"] == "skirt"
    )
    assert (
        attrs["format_version"] == 5 and len(attrs["model_hash"]) == 16 and attrs["body_name"] == "mannequin"
    )
    from hrr_garment.motion.motion import Motion
    from hrr_garment.motion.rotations import quat_to_matrix
    from hrr_garment.motion.skeleton import Skeleton

    played = Motion(
        quat_to_matrix(data.rotations[..., [3, 0, 1, 2]].astype(np.float64)),
        data.root_translation,
        30.0,
        skeleton=Skeleton(offsets=data.offsets),
    )
    assert np.abs(played.joint_positions - data.joints).max() < 1e-4  # the skeleton's motion gives the joints
    with np.load(clip) as z:
        arrays = dict(z)
    arrays["root_translation"] = arrays["root_translation"].copy()
    arrays["root_translation"][3] = np.nan
    bad = tmp_path / "nan.npz"
    np.savez(bad, **arrays)
    out2 = tmp_path / "bad.h5"
    assert animate_main([str(bad), "-o", str(out2), "--model", str(root / "model")]) == 2
    assert "nan.npz" in capsys.readouterr().err and not out2.exists()
    assert animate_main([str(clip), "-o", str(out2), "--model", str(tmp_path / "nothing")]) == 2
    assert "nothing" in capsys.readouterr().err and not out2.exists()
    half = [str(clip), "-o", str(out2), "--model", str(root / "model"), "--precision", "bfloat16"]
    lib = load_kernel()
    if lib is not None and lib.hrr_amx_ready():  # bfloat16 decoding runs where AMX is
        assert animate_main(half) == 0
        assert np.abs(read_animation_h5(out2).vertices - data.vertices).mean() <= 1e-3
        out2.unlink()
        monkeypatch.setattr(lib, "hrr_amx_ready", lambda: 0)  # and is refused clearly elsewhere
    assert animate_main(half) == 2
    assert "AMX" in capsys.readouterr().err and not out2.exists()


def test_hrr_animate_explains_bad_models_and_outputs(trained, tmp_path, capsys, mocap_dir):
    import shutil

    from hrr_garment.cli.animate import main as animate_main

    root, _, _ = trained
    clip = mocap_dir / "cmu" / "02_01.bvh"
    model = tmp_path / "model"
    shutil.copytree(root / "model", model)
    cases = [
        (
            [str(clip), "-o", str(tmp_path / "out.h5"), "--model", str(model), "--garment", "dress"],
            "animates a skirt, not a dress",
        ),
        (
            [str(clip), "-o", str(model / "bundle.json" / "out.h5"), "--model", str(model)],
            "not a writable folder",  # a file where the folder should be
        ),
        # a threshold that is no threshold names its flag (issue 48, reproducer 13)
        *(
            (
                [str(clip), "-o", str(tmp_path / "out.h5"), "--model", str(model), f"--tau={tau}"],
                "--tau: tau must be a finite number >= 0",
            )
            for tau in ("nan", "-1", "inf")
        ),
    ]
    for args, message in cases:
        assert animate_main(args) == 2
        assert message in capsys.readouterr().err
    weights = model / "decoder.safetensors"
    weights.write_bytes(weights.read_bytes()[:50])
    assert animate_main([str(clip), "-o", str(tmp_path / "out.h5"), "--model", str(model)]) == 2
    assert "decoder.safetensors" in capsys.readouterr().err
    unknown = tmp_path / "odd.bvh"
    unknown.write_text(clip.read_text().replace("LeftUpLeg", "Wing").replace("RightUpLeg", "Fin"))
    assert animate_main([str(unknown), "-o", str(tmp_path / "out.h5"), "--model", str(root / "model")]) == 2
    assert "odd.bvh" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.h5")) and not list(tmp_path.glob(".*tmp*"))
