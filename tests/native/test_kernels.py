"""The C kernels (hrr_garment.native) against their numpy references: capsule distances, push-out,
the strain limit, and the pinning of the OpenMP workers."""

import numpy as np
import pytest

from hrr_garment.motion.synth import synthesize
from tests.conftest import squeezed_skirt

pytestmark = pytest.mark.native


def test_native_capsule_distance_equals_numpy(rng):
    from hrr_garment.body.capsules import DEFAULT_BODY, capsule_signed_distance
    from hrr_garment.native import load_kernel
    from hrr_garment.native.capsules import capsule_sdf

    lib = load_kernel()
    if lib is None:
        pytest.skip("no C compiler")
    a, b = DEFAULT_BODY.pose_motion(synthesize("run", 0.2, seed=1))
    points = rng.normal(size=(500, 3)) * 0.3 + [0.0, 1.0, 0.0]
    d, n, _ = capsule_signed_distance(points, a[2], b[2], DEFAULT_BODY.radii)
    d2, n2 = capsule_sdf(lib, np.stack([points, points + 0.1]), a[2:4], b[2:4], DEFAULT_BODY.radii)
    assert np.allclose(d, d2[0], atol=1e-12) and np.allclose(n, n2[0], atol=1e-12)
    d3, _, _ = capsule_signed_distance(points + 0.1, a[3], b[3], DEFAULT_BODY.radii)
    assert np.allclose(d3, d2[1], atol=1e-12)  # each frame against its own capsules


@pytest.mark.parametrize(
    "follow", [None, 0, 6]
)  # None: whole-mesh loops; 0: culled, no follow (the default); 6: a follow
def test_native_push_out_equals_numpy(rng, follow):
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.inference.collision import EdgeLimits, PushOutSettings, _push_frames, mean_operator
    from hrr_garment.native import load_kernel
    from hrr_garment.native.body import PushSteps, push_out_frames

    lib = load_kernel()
    if lib is None:
        pytest.skip("no C compiler")
    motion = synthesize("dance", 0.3, seed=4)
    skirt, squeezed = squeezed_skirt(motion, 0.85)  # into the hips
    squeezed += rng.normal(scale=0.004, size=squeezed.shape)
    squeezed = squeezed.astype(np.float32)  # as decoders give them, and the kernel takes them
    a, b = DEFAULT_BODY.pose_motion(motion)
    mean = mean_operator(skirt.faces, len(skirt.vertices))
    limits = None if follow is None else EdgeLimits.of(skirt.faces, skirt.vertices)
    for rounds in (1, 2):
        settings = PushOutSettings(margin=0.002, smooth=4, rounds=rounds, depth=0.005, follow=follow or 0)
        ref = _push_frames(squeezed.astype(np.float64), (a, b, DEFAULT_BODY.radii), mean, settings, limits)
        steps = PushSteps(
            mean, 0.002, 4, rounds, 0.005, None if limits is None else limits.push_mesh(settings)
        )
        got = push_out_frames(lib, squeezed, (a, b, DEFAULT_BODY.radii), steps, threads=2)
        assert ref[1].max() > 0.05  # the test squeezes the skirt into the body
        assert np.abs(got[0] - ref[0]).max() < 1e-6
        assert np.allclose(got[1], ref[1]) and np.allclose(got[2], ref[2])
        for t in (0, 4):  # one frame at a time (streaming): the threads share the frame
            one = push_out_frames(
                lib, squeezed[t : t + 1], (a[t : t + 1], b[t : t + 1], DEFAULT_BODY.radii), steps, threads=2
            )
            assert np.array_equal(one[0][0], got[0][t]) and one[1][0] == got[1][t] and one[2][0] == got[2][t]
    if follow:  # the followers moved: more of the skirt than without the follow
        plain = _push_frames(
            squeezed.astype(np.float64),
            (a, b, DEFAULT_BODY.radii),
            mean,
            PushOutSettings(follow=0, depth=0.005),
            limits,
        )
        moved = lambda out: (np.abs(out[0] - squeezed).max(-1) > 0).mean()  # noqa: E731
        assert moved(ref) > moved(plain)


def test_the_push_limits_each_frame_as_the_strain_limit_does_after_it():
    """With a strain limit, the native push-out limits each frame right after its push, measuring
    only the edges of the vertices the push moved: what the strain limit run afterwards over every
    edge gives (within the float32 rounding of the pushed frames it then starts from), the same torn
    frames, and the same bits batched or a frame at a time."""
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.inference.collision import PUSH_OUT, EdgeLimits, mean_operator
    from hrr_garment.inference.strain_limit import native_strain_limit
    from hrr_garment.native import load_kernel
    from hrr_garment.native.body import PushSteps, limit_strain, push_out_frames

    lib = load_kernel()
    if lib is None:
        pytest.skip("no C compiler")
    motion = synthesize("dance", 0.3, seed=4)
    skirt, squeezed = squeezed_skirt(motion, 0.7)  # deep into the hips: pushes that tear
    squeezed = (squeezed + np.random.default_rng(3).normal(scale=0.004, size=squeezed.shape)).astype(
        np.float32
    )
    squeezed[::3, :, 0] += 1.0  # and frames a metre clear of the body
    a, b = DEFAULT_BODY.pose_motion(motion)
    limits = EdgeLimits.of(skirt.faces, skirt.vertices)
    steps = PushSteps(
        mean_operator(skirt.faces, len(skirt.vertices)), 0.002, 4, 1, 0.005, limits.push_mesh(PUSH_OUT)
    )
    strain = native_strain_limit(limits, PUSH_OUT.max_strain, PUSH_OUT.stretch_slack)
    pushed, before, after, untouched = push_out_frames(
        lib, squeezed, (a, b, DEFAULT_BODY.radii), steps, threads=2
    )
    assert not untouched.any()  # no limit asked for
    want, torn = limit_strain(lib, pushed, squeezed, strain, threads=2)
    assert 0 < torn.sum() < len(torn), torn
    limited = steps._replace(limit=strain)
    got, before2, after2, torn2 = push_out_frames(
        lib, squeezed, (a, b, DEFAULT_BODY.radii), limited, threads=2
    )
    assert (
        np.array_equal(torn2, torn) and np.abs(got - want).max() < 1e-6 and np.abs(got - pushed).max() > 1e-3
    )
    assert np.array_equal(before2, before) and np.array_equal(after2, after)  # the push's own fractions
    for t in np.r_[np.nonzero(torn)[0][:2], np.nonzero(~torn)[0][:1]]:  # one frame at a time (streaming)
        one = push_out_frames(
            lib, squeezed[t : t + 1], (a[t : t + 1], b[t : t + 1], DEFAULT_BODY.radii), limited, threads=2
        )
        assert np.array_equal(one[0][0], got[t]) and one[3][0] == torn[t]


def test_the_native_strain_limit_matches_the_numpy_reference():
    """The kernel's limits, torn frames and Gauss-Seidel passes are the reference's: same edges,
    colours and per-frame stop (the kernel measures only edges whose ends moved: the same result);
    both end with every edge within its limit."""
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.inference.edge_limits import EdgeLimits
    from hrr_garment.inference.strain_limit import (
        LIMIT_TOLERANCE_M,
        MAX_PUSH_STRAIN,
        OVER_RELAXATION,
        _limit_frames,
    )
    from hrr_garment.native import load_kernel
    from hrr_garment.native.body import StrainLimit, limit_strain

    lib = load_kernel()
    if lib is None:
        pytest.skip("no C compiler")
    skirt = make_garment("skirt", 300)
    limits = EdgeLimits.of(skirt.faces, skirt.vertices)
    rng = np.random.default_rng(2)
    unpushed = np.repeat(skirt.vertices[None], 4, 0).astype(np.float64)
    p = unpushed.copy()
    for t, size in enumerate([0.3, 0.05, 0.0, 0.12]):  # frame 2: nothing over the limit
        p[t, rng.choice(skirt.num_vertices, 5, replace=False)] += rng.normal(size=(5, 3)) * size
    limit = np.repeat(MAX_PUSH_STRAIN * limits.rest_length[None], 4, 0)
    ref = _limit_frames(p.copy(), limit, limits, 60)
    strain = StrainLimit(limits.native_arrays, MAX_PUSH_STRAIN, 60, LIMIT_TOLERANCE_M, OVER_RELAXATION)
    got, torn = limit_strain(lib, p, unpushed, strain, threads=2)
    assert torn.tolist() == [True, True, False, True]
    assert np.abs(got - ref).max() < 1e-8  # metres: float rounding of the same passes
    assert np.array_equal(got[2], p[2]) and np.abs(got - p).max() > 0.01
    assert (limits.lengths(got) - limit).max() < LIMIT_TOLERANCE_M * (1 + OVER_RELAXATION)  # converged
    one, _ = limit_strain(lib, p[3:], unpushed[3:], strain)
    assert np.array_equal(one[0], got[3])  # a frame's result does not depend on its batch
    # an unpushed frame stretched 1.45 x everywhere: with a slack of 0.1 its edges may reach 1.55 x
    stretched = unpushed * 1.45
    moved = stretched + (p - unpushed)
    slack_limit = np.maximum(MAX_PUSH_STRAIN, 1.45 + 0.1) * np.repeat(limits.rest_length[None], 4, 0)
    ref = _limit_frames(moved.copy(), slack_limit, limits, 60)
    got, torn = limit_strain(lib, moved, stretched, strain._replace(slack=0.1), threads=2)
    assert torn.tolist() == [True, True, False, True] and np.abs(got - ref).max() < 1e-8


def test_pinning_the_workers_leaves_the_caller_free(monkeypatch):
    """A stream pins its OpenMP workers, each to one CPU other than the caller's, and leaves the
    calling thread's own affinity as it was (it belongs to the user's program)."""
    import os

    from hrr_garment import native

    lib = native.load_kernel()
    allowed = os.sched_getaffinity(0)
    if lib is None or len(allowed) < 2:
        pytest.skip("needs the kernel and two CPUs")
    monkeypatch.delenv("OMP_PROC_BIND", raising=False)
    monkeypatch.setenv("HRR_PIN_THREADS", "1")
    monkeypatch.setattr(native.threads, "_pinned", {})
    native.pin_workers(2)
    assert os.sched_getaffinity(0) == allowed
    me = os.getpid()

    def affinity(task: str) -> set[int]:
        text = open(f"/proc/{me}/task/{task}/status").read()
        spans = next(line for line in text.splitlines() if line.startswith("Cpus_allowed_list")).split()[1]
        cpus = set()
        for span in spans.split(","):
            lo, _, hi = span.partition("-")
            cpus.update(range(int(lo), int(hi or lo) + 1))
        return cpus

    pinned = [cpus for task in os.listdir(f"/proc/{me}/task") if (cpus := affinity(task)) != allowed]
    assert pinned and all(len(cpus) == 1 and cpus <= allowed for cpus in pinned)
