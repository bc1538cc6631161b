"""Batched simulation (hrr_garment.sim.batch): sequences simulated together in one newton model,
each in its own world, give each sequence the frames it gets alone; an exploding instance falls
back to simulating alone with its retries; a cloth never touches another world's capsules."""

import numpy as np
import pytest

from hrr_garment.body.capsules import DEFAULT_BODY, frames_signed_distance
from hrr_garment.garment.templates import make_garment
from hrr_garment.garment.transfer import transfer_garment
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.plan import SequenceSpec
from tests.data.test_dataset_bodies import _dressed

pytestmark = pytest.mark.sim

# Batched frames against the same sequence alone, over a clip of 1 s after the 1.3 s lead-in, on
# Warp's CPU device. Measured: 0.0 (bit-identical): each instance keeps the colouring it has alone
# and the single-threaded CPU kernels sum each vertex's forces in the same order. The bound is
# float32 noise from a summation order that differs (a GPU's atomics, a ground contact listed
# before the capsules'), amplified over ~70 frames; a real coupling between worlds moves the cloth
# by centimetres.
BATCH_TOLERANCE_M = 1e-4


@pytest.fixture(scope="module")
def newton_installed():
    pytest.importorskip("newton", reason="the sim extra is not installed")


def _fast(**changes):
    from hrr_garment.sim.simulator import SimSettings

    return SimSettings(device="cpu", **{"settle_s": 0.1, "blend_s": 0.1, **changes})


def test_a_batch_gives_each_sequence_the_frames_it_gets_alone(newton_installed):
    """Three sequences of different clips and lengths, one on a taller, fuller body: each part of
    the batch is the part of that sequence simulated alone, statistics included."""
    from hrr_garment.sim.parts import SequenceJob, simulate_sequence, simulate_sequences
    from hrr_garment.sim.simulator import SimSettings

    garment = make_garment("skirt", 200)
    tall = _dressed(garment)
    specs = [
        SequenceSpec("walk_000", "walk", seed=0, seconds=1.0),
        SequenceSpec("spin_000", "spin", seed=1, seconds=0.7),
        SequenceSpec("walk_tall", "walk", seed=2, seconds=1.0, body_name="tall"),
    ]
    jobs = [
        SequenceJob(s, s.motion(), garment=garment, key=f"k{i}", body=tall if s.body_name else None)
        for i, s in enumerate(specs)
    ]
    config = SimSettings(device="cpu").to_dict()
    frames = []
    batched = simulate_sequences(jobs, config, progress=frames.append)
    assert (
        sum(frames) == sum(p.frames for p in batched) == 3 * 39 + 30 + 21 + 30
    )  # each instance's own frames only
    for job, part in zip(jobs, batched):
        alone = simulate_sequence(job.spec, job.motion, job.garment, config, job.key, body=job.body)
        assert part.failure is None and part.name == alone.name and part.key == alone.key
        assert (
            part.vertices.shape
            == alone.vertices.shape
            == (round(30 * job.spec.seconds), garment.num_vertices, 3)
        )
        assert np.abs(part.vertices - alone.vertices).max() <= BATCH_TOLERANCE_M
        assert part.info.get("body_name") == alone.info.get("body_name") and np.array_equal(
            part.motion.root_translation, alone.motion.root_translation
        )
        timing = ("sim_seconds",)
        assert {k: v for k, v in part.info["stats"].items() if k not in timing} == pytest.approx(
            {k: v for k, v in alone.info["stats"].items() if k not in timing}, abs=1e-4
        )


def _teleporting(clip: Motion, at: int) -> Motion:
    """``clip`` with the body jumping 3 m sideways at frame ``at``: no cloth survives that."""
    root = clip.root_translation.copy()
    root[at:, 0] += 3.0
    return Motion(clip.local_rotations, root, clip.fps, source="teleport")


def test_an_instance_that_explodes_is_simulated_alone_with_its_retries(newton_installed, monkeypatch):
    from hrr_garment.sim import batch
    from hrr_garment.sim.simulator import SimResult, SimulationExploded, simulate_garment

    garment = make_garment("skirt", 200)
    calm = synthesize("walk", 0.5, seed=0)
    items = [
        batch.BatchItem(garment, calm, DEFAULT_BODY),
        batch.BatchItem(garment, _teleporting(calm, 8), DEFAULT_BODY),
    ]
    alone_calls = []

    def spy(garment, motion, config, body, progress, collider):
        alone_calls.append(motion.source)
        return simulate_garment(garment, motion, config, body=body, progress=progress, collider=collider)

    monkeypatch.setattr(batch, "simulate_garment", spy)
    config = _fast(retries=1)
    calm_result, exploded = batch.simulate_batch(items, config)
    assert alone_calls == ["teleport"]  # only the exploded instance is simulated again, alone
    assert isinstance(exploded, SimulationExploded)
    assert "(10 substeps)" in str(exploded) and "(20 substeps)" in str(
        exploded
    )  # with the per-sequence retries
    assert isinstance(calm_result, SimResult) and calm_result.attempts == 1
    # the frozen instance left its neighbour alone
    assert (
        np.abs(calm_result.vertices - simulate_garment(garment, calm, config).vertices).max()
        <= BATCH_TOLERANCE_M
    )


def test_a_cloth_never_touches_another_worlds_capsules(newton_installed):
    """Two instances standing in the same place: the skirt on the mannequin (world 1) lies inside
    the fuller body of world 0, yet touches only its own body and the ground, and moves as it does
    alone. Arms-off is per instance."""
    from hrr_garment.sim.batch import BatchScene, step_batch
    from hrr_garment.sim.capsule_poses import arms_off_capsules
    from hrr_garment.sim.simulator import ClipRun, simulate_garment

    garment = make_garment("skirt", 200)
    fuller = DEFAULT_BODY.scaled(1.6)
    on_fuller = transfer_garment(garment, made_for=DEFAULT_BODY, body=fuller)[0]
    clip = synthesize("idle", 0.3, seed=0)
    config = _fast()
    runs = [
        ClipRun(on_fuller, clip, body=fuller, config=config),
        ClipRun(garment, clip, body=DEFAULT_BODY, config=config),
    ]
    a, b = fuller.pose_motion(clip)
    inside = (
        frames_signed_distance(garment.vertices[None].astype(np.float64), a[:1], b[:1], radii=fuller.radii)[0]
        < 0
    )
    assert inside.mean() > 0.3  # 44 %: its whole upper part starts inside world 0's capsules
    scene = BatchScene(runs, config)
    flags = scene.model.shape_flags.numpy().copy()
    scene.set_arm_contacts([False, True])
    arms0 = scene.arm_shapes[0]
    assert len(arms0) == len(arms_off_capsules(fuller)) == 6
    changed = np.flatnonzero(scene.model.shape_flags.numpy() != flags)
    assert np.array_equal(changed, sorted(arms0))  # instance 0's arms only
    scene.set_arm_contacts([True, True])
    assert np.array_equal(scene.model.shape_flags.numpy(), flags)
    dropped, _ = step_batch(scene, runs)
    assert dropped == {}
    count = int(scene.contacts.soft_contact_count.numpy()[0])
    particle = scene.contacts.soft_contact_particle.numpy()[:count]
    shape = scene.contacts.soft_contact_shape.numpy()[:count]
    particle_world = scene.model.particle_world.numpy()[particle]
    shape_world = scene.model.shape_world.numpy()[shape]
    assert count > 0 and ((shape_world == particle_world) | (shape_world == -1)).all()
    assert (particle_world == 1).any() and (shape_world == 1).any()  # world 1's cloth does meet its own body
    alone = simulate_garment(garment, clip, config).vertices
    assert np.abs(runs[1].recorded - alone).max() <= BATCH_TOLERANCE_M
