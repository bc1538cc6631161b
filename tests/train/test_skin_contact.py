"""The contact phase against the body the viewer sees (hrr_garment.train.skin_contact): the distance's
gradient is the finite difference of the collider's distance; the contacts of a dataset on a body
whose thighs bulge out of their capsules are that skin's distances, posed in the body frame as the
world poses it, so cloth the capsules let into a thigh is penalised and pushed out along the skin's
normal; points are left out only where the skin is farther than the reach; the mannequin keeps its
capsules."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from hrr_garment.body.capsules import capsule_signed_distance
from hrr_garment.body.mannequin import mannequin_record
from hrr_garment.body.mesh_distance import mesh_signed_distance, vertex_normals
from hrr_garment.body.mesh_record import BodyMesh
from hrr_garment.body.skin_collider import SkinColliderSettings, skin_collider
from hrr_garment.body.skin_envelope import SkinEnvelope
from hrr_garment.data.dataset import GarmentDataset
from hrr_garment.data.synthetic import write_synthetic_dataset
from hrr_garment.data.windows import build_windows
from hrr_garment.garment.dressing import DressedBody
from hrr_garment.garment.templates import make_garment
from hrr_garment.motion.frame import body_heading, to_body_frame
from hrr_garment.native import load_kernel
from hrr_garment.native.skin import SkinKernel
from hrr_garment.train.contact import BodyContacts
from hrr_garment.train.skin_contact import signed_distance, skin_query
from tests.body.limb import BulgingMannequin, bent, near_surface, skinned_limb

BULGE_M = 0.05


@pytest.mark.parametrize("native", [False, True])
def test_the_gradient_is_the_finite_difference_of_the_colliders_distance(native):
    limb = skinned_limb()
    collider = skin_collider(limb, SkinColliderSettings(voxel_m=0.01, padding_m=0.03))
    if native and load_kernel() is None:
        pytest.skip("no C compiler: the native kernel is not built")
    query = SkinKernel(collider, load_kernel()).query if native else collider.query
    rot, pos = bent(60.0)
    posed = limb.pose(rot[None], pos[None])[0]
    points, _ = near_surface(limb, posed, count=40)
    points = points[np.abs(query(points, rot, pos)[0]) > 0.004]  # off the surface, inside and out
    rng = np.random.default_rng(0)
    points += rng.normal(scale=0.002, size=points.shape)  # off the vertices' normals
    weights = rng.normal(size=len(points))

    def answer(p):
        return query(p, rot, pos)

    x = torch.tensor(points, dtype=torch.float64, requires_grad=True)
    (signed_distance(x, answer) * torch.from_numpy(weights)).sum().backward()
    h = 1e-6
    fd = np.stack(
        [
            (query(points + h * e, rot, pos)[0] - query(points - h * e, rot, pos)[0]) / (2 * h)
            for e in np.eye(3)
        ],
        1,
    )
    assert len(points) > 60 and (query(points, rot, pos)[0] < 0).mean() > 0.3
    assert np.abs(x.grad.numpy() - weights[:, None] * fd).max() < 1e-5 * np.abs(weights).max()


@pytest.fixture(scope="module")
def bulging_dataset(tmp_path_factory):
    """The simulator-free skirt dataset on the mannequin's skeleton and capsules whose own mesh (a
    fitted character's, body.json's) has thighs bulging 5 cm out of their capsules; its training
    windows (placeholder features and latents: the contacts read only which frames are stored)."""
    rest = BulgingMannequin(BULGE_M)
    record = replace(
        mannequin_record(), mesh=BodyMesh.of(rest.vertices, rest.faces, rest.joints, rest.weights)
    )
    skirt = make_garment("skirt", 300)
    root = tmp_path_factory.mktemp("bulging")
    ds = GarmentDataset(
        write_synthetic_dataset(root / "skirt.h5", skirt, bodies=[DressedBody("bulging", record, skirt)])
    )
    names = ds.splits["train"]
    frames = {n: ds.sequence(n).motion.num_frames for n in names}
    windows = build_windows(
        {n: np.zeros((t, 1), np.float32) for n, t in frames.items()},
        {n: np.zeros((t, 1, 1), np.float32) for n, t in frames.items()},
        names,
        window=8,
    )
    return ds, windows


def test_a_dataset_on_a_body_with_a_skin_is_kept_out_of_the_skin(bulging_dataset):
    ds, windows = bulging_dataset
    contacts = BodyContacts.of(ds, windows)
    assert contacts.against == {"visible": ["bulging"]}
    assert BodyContacts.of(ds, windows, "capsules").against == {"capsules": ["bulging"]}
    dressed = ds.bodies["bulging"]
    skin, motion = dressed.visible, ds.sequence(windows.names[0]).motion
    t = 20  # a stored frame mid-stride: the first sequence's frames come first
    rot, pos = motion.global_rotations[t], motion.joint_positions[t]
    posed = skin.pose(rot[None], pos[None])[0]
    # points a centimetre under the bulges' skin: outside the thighs' capsules, inside the skin
    a, b = (e[t] for e in dressed.body.pose_motion(motion))
    on_skin = capsule_signed_distance(posed, a, b, dressed.body.radii)[0]
    bulge = np.flatnonzero(on_skin > 0.03)
    under = posed[bulge] - 0.01 * vertex_normals(posed, skin.faces)[bulge]
    world, world_normal = skin_query(skin)(under, rot, pos)
    assert len(bulge) >= 8 and (capsule_signed_distance(under, a, b, dressed.body.radii)[0] > 0.015).all()
    assert (world < -0.008).all()
    # the same points in the body frame: the skin's distances, and pushed out along its normal
    x = torch.tensor(to_body_frame(np.broadcast_to(under, (motion.num_frames, *under.shape)), motion)[t])
    x = x.float().requires_grad_(True)
    d = contacts.distance(x[None], torch.tensor([t]), reach_m=0.002)[0]
    assert np.abs(d.detach().numpy() - world).max() < 1e-5
    torch.relu(0.002 - d).sum().backward()
    heading = body_heading(motion)[1][t]  # body frame -> world
    assert np.abs(x.grad.numpy() + world_normal @ heading).max() < 1e-5
    # against the capsules the same points are outside: nothing to push
    capsules = BodyContacts.of(ds, windows, "capsules").distance(x[None].detach(), torch.tensor([t]))
    assert (capsules > 0.015).all()


@pytest.mark.slow  # 6 s
def test_points_are_left_out_only_where_the_skin_is_farther_than_the_reach(bulging_dataset, rng):
    """A point is left out where the capsules grown to hold the posed skin lie farther than the
    reach (tests/body/test_skin_envelope.py): it gets their distance, which is more than the reach
    and no more than the distance to the skin; every other point gets the collider's answer, or
    the bound where that is positive and more (the collider's side wrong far from the skin). The
    capsules grown for a frame are kept for its next batch, and answer the same."""
    ds, windows = bulging_dataset
    contacts = BodyContacts.of(ds, windows)
    dressed = ds.bodies["bulging"]
    skin, motion = dressed.visible, ds.sequence(windows.names[0]).motion
    rows = np.array([5, 17, 30, 44])
    rot, pos = motion.global_rotations[rows], motion.joint_positions[rows]
    posed = skin.pose(rot, pos)
    world = posed[:, rng.integers(0, posed.shape[1], 300)] + rng.normal(scale=0.05, size=(len(rows), 300, 3))
    everywhere = np.zeros((motion.num_frames, *world.shape[1:]))
    everywhere[rows] = world
    x = torch.from_numpy(to_body_frame(everywhere, motion)[rows])
    reach = 0.01
    # two of the frames asked first: the call after keeps their grown capsules and makes the others'
    contacts.distance(x[:2], torch.from_numpy(rows[:2]), reach_m=reach)
    left_out = contacts.distance(x, torch.from_numpy(rows), reach_m=reach).numpy()
    # ... and a batch of frames all met before, in another order, gets the same answers
    again = contacts.distance(x.flip(0), torch.from_numpy(rows[::-1].copy()), reach_m=reach).numpy()
    assert np.array_equal(again, left_out[::-1])
    every = contacts.distance(x, torch.from_numpy(rows), reach_m=np.inf).numpy()
    a, b, radii = SkinEnvelope.of(skin, dressed.body).grown(rot, pos)
    bound = np.stack([capsule_signed_distance(w, *c)[0] for w, c in zip(world, zip(a, b, radii))])
    far = bound > reach
    assert 0.2 < far.mean() < 0.9
    # near the skin the collider's answer, raised to the bound where the bound says outside
    near = np.where(bound > 0.0, np.maximum(every, bound), every)
    assert (
        np.abs(left_out[~far] - near[~far]).max() < 1e-6 and np.abs(left_out[far] - bound[far]).max() < 1e-6
    )
    exact = np.stack([np.abs(mesh_signed_distance(w, p, skin.faces)) for w, p in zip(world, posed)])
    assert (bound[far] <= exact[far] + 1e-9).all()
    raised = left_out != every
    assert (exact[raised] >= left_out[raised] - 1e-9).all()
    in_world = skin_query(skin)(world[0], rot[0], pos[0])[0]
    assert (
        np.isclose(in_world, every[0], rtol=0.0, atol=1e-5).mean() > 0.99
    )  # the collider's, posed in the world


def test_the_setting_is_checked_and_keys_the_stage_only_where_a_skin_changes_the_phase(
    bulging_dataset, tmp_path
):
    """contact_body is validated; it leaves the main training's key alone, and the stage's key moves
    with it only on bodies with a skin: on the mannequin's capsules the key is the one from before
    the setting existed (its finished stages are reused as they are)."""
    from hrr_garment.models.codespace import CodeSpaceSettings
    from hrr_garment.settings import SettingsError
    from hrr_garment.train.codespace_resume import stage_keys
    from hrr_garment.train.codespace_settings import CodeSpaceTrainSettings

    with pytest.raises(SettingsError, match="contact_body must be one of visible, capsules"):
        CodeSpaceTrainSettings(contact_body="skin")
    mannequin = GarmentDataset(write_synthetic_dataset(tmp_path / "skirt.h5", make_garment("skirt", 300)))
    for ds, skinned in ((mannequin, False), (bulging_dataset[0], True)):
        latents = {n: np.zeros((2, 1, 1), np.float32) for n in ds.names}

        def keys(**settings):
            train = CodeSpaceTrainSettings(**settings)
            return stage_keys(CodeSpaceSettings(), train, {}, latents, ds)

        visible, capsules = keys(contact_steps=10), keys(contact_steps=10, contact_body="capsules")
        assert visible[1] == capsules[1] == keys()[0]  # the main training's key: as without the phase
        assert (visible[0] != capsules[0]) == skinned
        assert keys(contact_body="capsules") == keys()  # no phase: nothing to key
