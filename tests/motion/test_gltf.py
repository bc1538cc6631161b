"""Motion from glTF / GLB animations: skinned characters built here with pygltflib, compared with the
same clips written as BVH; units through the node tree, interpolation, animation choice, bad files."""

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from hrr_garment import load_motion, synthesize
from hrr_garment.errors import MotionError
from hrr_garment.motion.bvh_write import write_bvh
from hrr_garment.motion.gltf_animation import AnimationChannel, gltf_animations, sample_channel
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.rotations import axis_angle_to_matrix, matrix_to_quat
from hrr_garment.motion.skeleton import CANONICAL, JOINT_NAMES, PARENTS, forward_kinematics

pygltflib = pytest.importorskip("pygltflib")

BUNDLE = Path(__file__).resolve().parents[1] / "fixtures" / "bundle-31b4ef9"  # a small trained model

MIXAMO = {
    "pelvis": "Hips",
    "spine1": "Spine",
    "spine2": "Spine1",
    "spine3": "Spine2",
    "neck": "Neck",
    "head": "Head",
    "hip": "UpLeg",
    "knee": "Leg",
    "ankle": "Foot",
    "foot": "ToeBase",
    "collar": "Shoulder",
    "shoulder": "Arm",
    "elbow": "ForeArm",
    "wrist": "Hand",
}


def mixamo_names(prefix: str = "mixamorig:") -> list[str]:
    """The canonical joints under Mixamo's names (``mixamorig:LeftArm`` ...)."""
    out = []
    for name in JOINT_NAMES:
        if name[:2] in ("l_", "r_"):
            out.append(prefix + ("Left" if name[0] == "l" else "Right") + MIXAMO[name[2:]])
        else:
            out.append(prefix + MIXAMO[name])
    return out


@dataclass
class Rig:
    """How a test character is laid out: its joint names, the metres per unit of its joint
    transforms (0.01: centimetres under an armature scaled by 0.01), the armature's rotation (an
    axis-angle; Z-up authoring turned Y up), each joint's rest orientation in the world (bone axes
    as Mixamo/Blender give them, not the identity), the keyframes' interpolation and spacing."""

    names: list[str] = field(default_factory=mixamo_names)
    unit: float = 1.0
    armature: tuple = (0.0, 0.0, 0.0)
    orient: np.ndarray | None = None
    interpolation: str = "LINEAR"
    every: int = 1  # keep every n-th frame of the 30 fps clip as a key
    skin: bool = True


class _Blob:
    def __init__(self, gl):
        self.gl, self.data = gl, bytearray()

    def add(self, array: np.ndarray, kind: str) -> int:
        array = np.ascontiguousarray(array, dtype=np.float32)
        view = pygltflib.BufferView(buffer=0, byteOffset=len(self.data), byteLength=array.nbytes)
        self.data += array.tobytes()
        self.gl.bufferViews.append(view)
        acc = pygltflib.Accessor(
            bufferView=len(self.gl.bufferViews) - 1,
            componentType=pygltflib.FLOAT,
            count=len(array),
            type=kind,
        )
        if kind == "SCALAR":
            acc.min, acc.max = [float(array.min())], [float(array.max())]
        self.gl.accessors.append(acc)
        return len(self.gl.accessors) - 1


def _xyzw(rot: np.ndarray) -> np.ndarray:
    return matrix_to_quat(rot)[..., [1, 2, 3, 0]]


def _animation(blob: _Blob, name: str, motion, rig: Rig) -> "pygltflib.Animation":
    """Rotation channels on every joint and a translation channel on the root, in the rig's layout."""
    keys = np.arange(0, motion.num_frames, rig.every)
    local = motion.local_rotations.astype(np.float64)[keys]
    glob, pos = forward_kinematics(
        local, motion.root_translation[keys], CANONICAL.offsets.astype(np.float64), PARENTS
    )
    orient = rig.orient if rig.orient is not None else np.broadcast_to(np.eye(3), (len(JOINT_NAMES), 3, 3))
    arm = axis_angle_to_matrix(np.asarray(rig.armature, dtype=np.float64))
    times = blob.add(keys / motion.fps, "SCALAR")
    samplers, channels = [], []
    for j, p in enumerate(PARENTS):
        if p < 0:
            rot = arm.T @ glob[:, j] @ orient[j]
            trans = blob.add(pos[:, j] @ arm / rig.unit, "VEC3")  # arm.T @ p for each row
            samplers.append(
                pygltflib.AnimationSampler(input=times, output=trans, interpolation=rig.interpolation)
            )
            channels.append(
                pygltflib.AnimationChannel(
                    sampler=len(samplers) - 1,
                    target=pygltflib.AnimationChannelTarget(node=j + 1, path="translation"),
                )
            )
        else:
            rot = orient[p].T @ local[:, j] @ orient[j]
        samplers.append(
            pygltflib.AnimationSampler(
                input=times, output=blob.add(_xyzw(rot), "VEC4"), interpolation=rig.interpolation
            )
        )
        channels.append(
            pygltflib.AnimationChannel(
                sampler=len(samplers) - 1,
                target=pygltflib.AnimationChannelTarget(node=j + 1, path="rotation"),
            )
        )
    return pygltflib.Animation(name=name, samplers=samplers, channels=channels)


def write_character(path, clips: dict, rig: Rig = Rig()) -> None:
    """A GLB (or .gltf with the buffer embedded) of an armature node over the canonical skeleton
    named and laid out as ``rig`` says, with one animation per entry of ``clips`` (name -> motion)."""
    gl = pygltflib.GLTF2()
    blob = _Blob(gl)
    orient = rig.orient if rig.orient is not None else np.broadcast_to(np.eye(3), (len(JOINT_NAMES), 3, 3))
    arm = axis_angle_to_matrix(np.asarray(rig.armature, dtype=np.float64))
    rest_root = np.array([0.0, 0.96, 0.0])
    nodes = [
        pygltflib.Node(name="Armature", children=[1], rotation=_xyzw(arm).tolist(), scale=[rig.unit] * 3)
    ]
    for j, p in enumerate(PARENTS):
        if p < 0:
            t, r = arm.T @ rest_root / rig.unit, arm.T @ orient[j]
        else:
            t, r = orient[p].T @ CANONICAL.offsets[j].astype(np.float64) / rig.unit, orient[p].T @ orient[j]
        children = [c + 1 for c, q in enumerate(PARENTS) if q == j]
        nodes.append(
            pygltflib.Node(
                name=rig.names[j],
                translation=t.tolist(),
                rotation=_xyzw(r).tolist(),
                children=children or None,
            )
        )
    gl.nodes = nodes
    gl.scenes = [pygltflib.Scene(nodes=[0])]
    gl.scene = 0
    if rig.skin:
        gl.skins = [pygltflib.Skin(joints=list(range(1, len(JOINT_NAMES) + 1)), skeleton=1)]
    gl.animations = [_animation(blob, name, motion, rig) for name, motion in clips.items()]
    gl.buffers = [pygltflib.Buffer(byteLength=len(blob.data))]
    gl.set_binary_blob(bytes(blob.data))
    if str(path).endswith(".gltf"):
        gl.convert_buffers(pygltflib.BufferFormat.DATAURI)
        gl.save_json(str(path))
    else:
        gl.save_binary(str(path))


def write_canonical_bvh(path, motion) -> None:
    write_bvh(
        path,
        list(JOINT_NAMES),
        list(PARENTS),
        CANONICAL.offsets,
        motion.local_rotations.astype(np.float64),
        motion.root_translation.astype(np.float64),
        1.0 / motion.fps,
    )


def assert_same_motion(a, b, tol_m: float = 1e-3) -> None:
    assert a.num_frames == b.num_frames and a.fps == b.fps == 30.0
    gap = np.abs(a.joint_positions - b.joint_positions).max()
    assert gap < tol_m, f"joint positions differ by {gap * 1000:.3f} mm"


@pytest.fixture(scope="module")
def walk():
    return synthesize("walk", 1.0, seed=0)


@pytest.fixture(scope="module")
def spin():
    return synthesize("spin", 1.0, seed=1)


@pytest.fixture(scope="module")
def walk_bvh_motion(walk, tmp_path_factory):
    path = tmp_path_factory.mktemp("bvh") / "walk.bvh"
    write_canonical_bvh(path, walk)
    return load_motion(path)


def test_glb_gives_the_motion_its_bvh_gives(tmp_path, walk, walk_bvh_motion):
    path = tmp_path / "character.glb"
    write_character(path, {"Walk": walk})
    motion = load_motion(path)
    assert motion.source_skeleton == "mixamo"
    assert motion.source_height_m == pytest.approx(walk_bvh_motion.source_height_m, rel=1e-5)
    assert_same_motion(motion, walk_bvh_motion)
    # and the same as the clip itself (the canonical rig retargets onto itself)
    assert np.abs(motion.joint_positions - walk.joint_positions).max() < 1e-3


def test_centimetre_armature_turned_from_z_up_and_bone_axes(tmp_path, walk, walk_bvh_motion, rng):
    """FBX -> glTF: joints in centimetres under an armature node scaled by 0.01 and turned from Z up,
    each bone with its own rest axes: the node tree above the root joint is applied."""
    orient = axis_angle_to_matrix(rng.normal(size=(len(JOINT_NAMES), 3)))
    rig = Rig(names=mixamo_names("mixamorig_"), unit=0.01, armature=(-np.pi / 2, 0.0, 0.0), orient=orient)
    path = tmp_path / "centimetres.glb"
    write_character(path, {"Walk": walk}, rig)
    nodes = pygltflib.GLTF2().load(str(path)).nodes
    assert nodes[0].scale == [0.01] * 3 and nodes[1].translation[2] == pytest.approx(
        96.0
    )  # cm, the armature's z up
    motion = load_motion(path)
    assert motion.source_height_m == pytest.approx(walk_bvh_motion.source_height_m, rel=1e-4)
    assert_same_motion(motion, walk_bvh_motion)


def test_a_long_animation_composed_in_passes_is_the_one_pass_motion(tmp_path, walk, rng, monkeypatch):
    """The node tree is composed a few thousand frames at a time (memory follows the joints, not
    every node's temporaries): passes of 7 frames give the same motion to the bit, under an armature
    scaled and turned, with bone axes, at a key rate filtered down (keys 4 x the output rate)."""
    from hrr_garment.motion import gltf

    orient = axis_angle_to_matrix(rng.normal(size=(len(JOINT_NAMES), 3)))
    rig = Rig(names=mixamo_names("mixamorig_"), unit=0.01, armature=(-np.pi / 2, 0.0, 0.0), orient=orient)
    fast = Motion(walk.local_rotations, walk.root_translation, 120.0)  # keyed at 120 fps
    path = tmp_path / "fast.glb"
    write_character(path, {"Walk": fast}, rig)
    whole = load_motion(path)
    monkeypatch.setattr(gltf, "WORLD_CHUNK", 7)
    passes = load_motion(path)
    assert whole.num_frames == passes.num_frames == 8
    assert np.array_equal(whole.local_rotations, passes.local_rotations)
    assert np.array_equal(whole.root_translation, passes.root_translation)


def test_centimetres_without_a_scaling_node_are_detected_or_given(tmp_path, walk, walk_bvh_motion):
    """A file written in centimetres with no node scaling them (not glTF's metres) is detected by
    its standing height, as BVH units are; --unit-scale says it outright."""
    path = tmp_path / "no_scale.glb"
    write_character(path, {"Walk": walk}, Rig(unit=0.01))
    gl = pygltflib.GLTF2().load(str(path))
    gl.nodes[0].scale = None
    gl.save_binary(str(path))
    for motion in (load_motion(path), load_motion(path, unit_scale=0.01)):
        assert motion.source_height_m == pytest.approx(
            walk_bvh_motion.source_height_m, rel=1e-4
        )  # metres, not 170
        assert_same_motion(motion, walk_bvh_motion)
    assert load_motion(path, unit_scale=0.012).source_height_m == pytest.approx(
        1.2 * walk_bvh_motion.source_height_m, rel=1e-4
    )
    with pytest.raises(MotionError, match="--unit-scale 1e-09 stands its skeleton"):  # issue 88
        load_motion(path, unit_scale=1e-9)


def test_embedded_gltf_and_mixamo_names_without_colon(tmp_path, walk, walk_bvh_motion):
    path = tmp_path / "character.gltf"
    write_character(path, {"Walk": walk}, Rig(names=mixamo_names("mixamorig")))  # three.js: mixamorigHips
    motion = load_motion(path)
    assert motion.source_skeleton == "mixamo"
    assert_same_motion(motion, walk_bvh_motion)


def test_step_interpolation_holds_each_key(tmp_path, walk):
    """Keys at 10 fps with STEP: each key is held for three 30 fps frames (LINEAR would blend)."""
    keys = (walk.num_frames - 1) // 3 * 3 + 1
    hold = np.arange(keys) // 3 * 3
    held = Motion(walk.local_rotations[hold], walk.root_translation[hold], walk.fps)
    bvh = tmp_path / "held.bvh"
    write_canonical_bvh(bvh, held)
    path = tmp_path / "step.glb"
    write_character(path, {"Walk": walk.slice(0, keys)}, Rig(interpolation="STEP", every=3))
    stepped = load_motion(path)
    assert_same_motion(stepped, load_motion(bvh))
    # the same keys blended linearly move on every frame
    write_character(path, {"Walk": walk.slice(0, keys)}, Rig(every=3))
    linear = load_motion(path)
    assert np.abs(linear.joint_positions - stepped.joint_positions).max() > 0.01


def test_cubic_spline_follows_its_tangents():
    """CUBICSPLINE: Hermite between keys with tangents per second; a cubic is reproduced exactly."""
    times = np.array([0.0, 2.0])
    # x(t) = t^3 / 8 on [0, 2]: values 0 and 1, slopes 0 and 1.5 per second
    values = np.zeros((2, 3, 3))
    values[1, 1, 0], values[1, 0, 0] = 1.0, 1.5
    channel = AnimationChannel(0, "translation", times, values, "CUBICSPLINE")
    t = np.linspace(0.0, 2.0, 9)
    np.testing.assert_allclose(sample_channel(channel, t)[:, 0], t**3 / 8, atol=1e-12)
    # a rotation stays a unit quaternion
    quats = np.zeros((2, 3, 4))
    quats[:, 1] = [[1.0, 0, 0, 0], [0.0, 1, 0, 0]]
    quats[0, 2] = [0, 1.0, 0, 0]
    out = sample_channel(
        AnimationChannel(0, "rotation", np.array([0.0, 1.0]), quats, "CUBICSPLINE"), np.linspace(0, 1, 5)
    )
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0)


def test_cubic_spline_file_matches_linear_at_its_keys(tmp_path, walk, walk_bvh_motion):
    """Keys on every 30 fps frame: the spline passes through each key's value (the middle of its triple)."""
    path = tmp_path / "cubic.glb"
    write_character(path, {"Walk": walk})
    gl = pygltflib.GLTF2().load(str(path))
    blob = bytearray(gl.binary_blob())
    for sampler in gl.animations[0].samplers:
        acc = gl.accessors[sampler.output]
        width = 4 if acc.type == "VEC4" else 3
        view = gl.bufferViews[acc.bufferView]
        values = np.frombuffer(
            bytes(blob[view.byteOffset : view.byteOffset + view.byteLength]), np.float32
        ).reshape(-1, width)
        triple = np.stack(
            [np.full_like(values, 7.0), values, np.full_like(values, -7.0)], 1
        )  # tangents never land on keys
        gl.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=len(blob), byteLength=triple.nbytes))
        blob += triple.tobytes()
        gl.accessors.append(
            pygltflib.Accessor(
                bufferView=len(gl.bufferViews) - 1,
                componentType=pygltflib.FLOAT,
                count=3 * acc.count,
                type=acc.type,
            )
        )
        sampler.output, sampler.interpolation = len(gl.accessors) - 1, "CUBICSPLINE"
    gl.buffers[0].byteLength = len(blob)
    gl.set_binary_blob(bytes(blob))
    gl.save_binary(str(path))
    assert_same_motion(load_motion(path), walk_bvh_motion)


def test_animation_by_name_and_by_index(tmp_path, walk, spin, walk_bvh_motion):
    path = tmp_path / "two.glb"
    write_character(path, {"Walk": walk, "Spin": spin})
    bvh = tmp_path / "spin.bvh"
    write_canonical_bvh(bvh, spin)
    spin_bvh = load_motion(bvh)
    assert_same_motion(load_motion(path), walk_bvh_motion)  # the first by default
    assert_same_motion(load_motion(path, animation="Spin"), spin_bvh)
    assert_same_motion(load_motion(path, animation=1), spin_bvh)
    assert_same_motion(load_motion(path, animation="1"), spin_bvh)  # as the command line gives it
    found = gltf_animations(path)
    assert [a.name for a in found] == ["Walk", "Spin"]
    assert found[0].keyframes == walk.num_frames and found[0].duration_s == pytest.approx(
        (walk.num_frames - 1) / 30, abs=1e-6
    )
    with pytest.raises(MotionError, match="no animation named 'Run'.*'Walk'.*'Spin'") as err:
        load_motion(path, animation="Run")
    assert str(path) in str(err.value)
    with pytest.raises(MotionError, match="no animation 5; the file's animations are 0: 'Walk', 1: 'Spin'"):
        load_motion(path, animation=5)


def test_joint_map_file(tmp_path, walk, walk_bvh_motion):
    """Joints no scheme knows are matched by a --joint-map YAML, as for BVH."""
    names = [f"bone_{j:02d}" for j in range(len(JOINT_NAMES))]
    path = tmp_path / "odd.glb"
    write_character(path, {"Walk": walk}, Rig(names=names))
    with pytest.raises(MotionError, match="joint-map"):
        load_motion(path)
    joint_map = tmp_path / "map.yaml"
    joint_map.write_text("".join(f"{c}: {s}\n" for c, s in zip(JOINT_NAMES, names)))
    motion = load_motion(path, joint_map=joint_map)
    assert motion.source_skeleton == "custom"
    assert_same_motion(motion, walk_bvh_motion)


def _bad_files(tmp_path, walk) -> dict:
    good = tmp_path / "good.glb"
    write_character(good, {"Walk": walk})
    data = good.read_bytes()
    files = {
        "truncated": (tmp_path / "truncated.glb", "cut short"),
        "header": (tmp_path / "header.glb", "not a readable glTF"),
        "no_skin": (tmp_path / "no_skin.glb", "no skin"),
        "no_anim": (tmp_path / "no_anim.glb", "no animations"),
        "json": (tmp_path / "broken.gltf", "not a readable glTF"),
    }
    files["truncated"][0].write_bytes(data[: len(data) - 200])  # the binary chunk cut short
    files["header"][0].write_bytes(data[:30])  # cut inside the JSON chunk
    write_character(files["no_skin"][0], {"Walk": walk}, Rig(skin=False))
    write_character(files["no_anim"][0], {})
    files["json"][0].write_text('{"asset": {"version": "2.0"}, "nodes": [')
    return files


def test_bad_files_are_refused_naming_the_file(tmp_path, walk):
    for path, phrase in _bad_files(tmp_path, walk).values():
        with pytest.raises(MotionError, match=phrase) as err:
            load_motion(path)
        assert str(path) in str(err.value)
    bvh = tmp_path / "walk.bvh"
    write_canonical_bvh(bvh, walk)
    with pytest.raises(MotionError, match="only glTF / GLB files hold named animations"):
        load_motion(bvh, animation="Walk")


def test_hrr_motion_info_lists_animations(tmp_path, walk, spin, capsys):
    import json

    from hrr_garment.cli.motion import main

    path = tmp_path / "character.glb"
    write_character(path, {"Walk": walk, "Spin": spin})
    assert main(["info", str(path), "--animation", "Spin", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["animation"] == "Spin" and info["source_skeleton"] == "mixamo"
    assert [a["name"] for a in info["animations"]] == ["Walk", "Spin"]
    assert info["animations"][1]["frames_30fps"] == info["frames"] == spin.num_frames
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "0: 'Walk'" in out and "1: 'Spin'" in out
    assert main(["info", str(path), "--animation", "Run"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "'Walk'" in err


def test_command_lines_refuse_bad_glb_with_exit_2(tmp_path, walk, capsys):
    from hrr_garment.cli.animate import main as animate
    from hrr_garment.cli.motion import main as motion_cli

    for path, phrase in _bad_files(tmp_path, walk).values():
        assert motion_cli(["info", str(path)]) == 2
        err = capsys.readouterr().err
        assert str(path) in err and phrase in err and "Traceback" not in err
    path = tmp_path / "good.glb"
    code = animate([str(path), "-o", str(tmp_path / "out.h5"), "--model", str(BUNDLE), "--animation", "Run"])
    err = capsys.readouterr().err
    assert code == 2 and str(path) in err and "no animation named 'Run'" in err
    assert not (tmp_path / "out.h5").exists()


def test_simulate_plan_takes_glb_files(tmp_path, walk):
    """hrr-simulate --motions character.glb: a motion file (its first animation), in folders too."""
    from hrr_garment.sim.plan import plan_sequences
    from hrr_garment.sim.preset import load_preset
    from hrr_garment.sim.sources import resolve_motion_entries

    path = tmp_path / "clips" / "character.glb"
    path.parent.mkdir()
    write_character(path, {"Walk": walk})
    assert resolve_motion_entries([str(path)]) == [path.resolve()]
    assert resolve_motion_entries([str(path.parent)]) == [path.resolve()]
    specs = plan_sequences(load_preset("tiny"), motions=[str(path)])
    assert [(s.kind, s.name) for s in specs] == [("file", "character")]
    assert np.abs(specs[0].motion().joint_positions - walk.joint_positions).max() < 1e-3


def test_without_pygltflib_the_extra_is_named(tmp_path, walk, monkeypatch, capsys):
    from hrr_garment.cli.motion import main

    path = tmp_path / "character.glb"
    write_character(path, {"Walk": walk})
    monkeypatch.setitem(
        __import__("sys").modules, "pygltflib", None
    )  # as if the export extra were not installed
    with pytest.raises(ImportError, match=r"pip install 'hrr_garment\[export\]'"):
        load_motion(path)
    assert main(["info", str(path)]) == 2
    assert "hrr_garment[export]" in capsys.readouterr().err


def test_hrr_animate_a_glb_animation(tmp_path, walk, spin, capsys):
    """hrr-animate character.glb --animation Spin: the garment follows the second animation."""
    import h5py

    from hrr_garment.cli.animate import main as animate

    path = tmp_path / "character.glb"
    write_character(path, {"Walk": walk, "Spin": spin})
    out = tmp_path / "out.h5"
    assert animate([str(path), "--animation", "Spin", "-o", str(out), "--model", str(BUNDLE)]) == 0, (
        capsys.readouterr().err
    )
    with h5py.File(out, "r") as f:
        assert f["vertices"].shape[0] == spin.num_frames


def test_gltf_with_a_bin_file_beside_it(tmp_path, walk, walk_bvh_motion):
    glb = tmp_path / "character.glb"
    write_character(glb, {"Walk": walk})
    gl = pygltflib.GLTF2().load(str(glb))
    gl.buffers[0].uri = "character%20data.bin"  # URIs are percent-encoded
    (tmp_path / "character data.bin").write_bytes(gl.binary_blob())
    gl.set_binary_blob(b"")
    path = tmp_path / "character.gltf"
    gl.save_json(str(path))
    assert_same_motion(load_motion(path), walk_bvh_motion)
    gl.buffers[0].uri = "../elsewhere.bin"
    gl.save_json(str(path))
    with pytest.raises(MotionError, match="not a file beside the .gltf"):
        load_motion(path)


def test_a_node_cycle_is_refused(tmp_path, walk):
    path = tmp_path / "cycle.glb"
    write_character(path, {"Walk": walk})
    gl = pygltflib.GLTF2().load(str(path))
    gl.nodes[0].children = []  # the armature no longer holds the hips ...
    gl.nodes[22].children = [1]  # ... the right wrist does: wrist -> hips -> ... -> wrist
    gl.save_binary(str(path))
    with pytest.raises(MotionError, match="cycle"):
        load_motion(path)


def test_a_glb_keyed_at_120_fps_is_filtered_down_as_its_bvh_is(tmp_path, walk):
    """A 120 fps capture baked to keys reads as the same capture in a BVH: low-pass filtered to 30
    fps (motion/resample.py), not every fourth key."""
    fast = Motion(walk.local_rotations, walk.root_translation, 120.0)  # the walk played 4 x faster
    bvh = tmp_path / "fast.bvh"
    write_canonical_bvh(bvh, fast)
    write_character(tmp_path / "fast.glb", {"Fast": fast})
    from_bvh, from_glb = load_motion(bvh), load_motion(tmp_path / "fast.glb")
    assert_same_motion(from_glb, from_bvh, tol_m=2e-3)
    decimated = Motion(fast.local_rotations[::4], fast.root_translation[::4], 30.0)
    assert np.abs(from_glb.joint_positions - decimated.joint_positions[: from_glb.num_frames]).max() > 5e-3
