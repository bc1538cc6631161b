from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from hrr_garment.paths import find_mocap_dir

CMU_CLIPS = ("02_01", "131_01", "131_03")

# The tiers (pyproject's markers, docs/testing.md): a test that uses one of these session fixtures,
# directly or through another fixture, is marked by what the fixture does the first time it runs
SLOW_FIXTURES = {
    "trained",
    "paper_model",
    "artist_model",
    "bodies_model",
    "materials_model",
}  # train a tiny model: tens of seconds and more
SIM_FIXTURES = {"artist_model"}  # runs hrr-simulate (newton/Warp)


def pytest_configure(config):
    """Under pytest-xdist (``make test`` runs ``-n auto``), each worker takes its share of the
    cores for torch and the kernels: two workers of two threads each on two cores ran every test
    1.3-1.7 x slower than alone, for a suite only 17 % faster."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if workers > 1:
        import torch

        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
        torch.set_num_threads(max(1, cores // workers))


def pytest_collection_modifyitems(config, items):
    """Mark the tests that use the training and simulating fixtures ``slow`` and ``sim``."""
    for item in items:
        used = set(getattr(item, "fixturenames", ()))
        if used & SLOW_FIXTURES:
            item.add_marker(pytest.mark.slow)
        if used & SIM_FIXTURES:
            item.add_marker(pytest.mark.sim)


@pytest.fixture(scope="session")
def mocap_dir() -> Path:
    found = find_mocap_dir()
    if found is None:
        pytest.skip("shared/data/mocap not found (set HRR_MOCAP_DIR)")
    return found


@pytest.fixture(scope="session")
def cmu_motions(mocap_dir):
    from hrr_garment import load_motion

    return {name: load_motion(mocap_dir / "cmu" / f"{name}.bvh") for name in CMU_CLIPS}


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


def write_meta(folder: Path, meta: dict) -> None:
    """bundle.json as hrr_garment writes it, its manifest hash over the content: a test's edit that
    stands for an older or another bundle, not for tampering (tests/artifacts test that)."""
    import json

    from hrr_garment.artifacts.manifest import manifest_hash

    version = meta.get("format_version")
    if isinstance(version, int) and not isinstance(version, bool) and version >= 4:
        meta = {**meta, "manifest_hash": manifest_hash(meta)}
    (Path(folder) / "bundle.json").write_text(json.dumps(meta))


def with_manifest(monkeypatch, bundle, **changes) -> None:
    """``bundle`` (loaded) with fields of its typed manifest replaced for the test (``residual=``,
    ``auto=``: typed sections), as a bundle.json with them would load."""
    import dataclasses

    monkeypatch.setattr(bundle, "manifest", dataclasses.replace(bundle.manifest, **changes))


def synthetic_dataset(path, garment):
    """The simulator-free dataset (hrr_garment.data.synthetic): its garment follows the motion."""
    from hrr_garment.data.synthetic import write_synthetic_dataset

    return write_synthetic_dataset(path, garment)


TINY_TRAINING = """
autoencoder:
  model: {channels: [8, 16]}
  train: {epochs: 3, batch_size: 16, max_minutes: null, target_mm: null}
codespace:
  model: {groups: 16, classes: 4, embedding_dim: 4, hidden: 64, motion_hidden: 32, attention_heads: 2}
  train: {epochs: 4, learning_rate: 0.001, plateau_patience: 2, patience: 5, max_minutes: null}
subspace:
  model: {max_components: 48, hidden: 64}
  train: {epochs: 30, pca_frames: 4000}
"""


def train_tiny(
    data: Path,
    folder: Path,
    config: Path,
    stages: tuple[str, ...] | None = None,
    overrides: dict | None = None,
):
    """Train through the library (:func:`hrr_garment.pipeline.train.train_model`) as ``hrr-train
    --dataset DATA --config CONFIG -o FOLDER`` does: the quick preset's settings under the config's."""
    from hrr_garment.pipeline.train import STAGES, TrainSettings, train_model
    from hrr_garment.sim.preset import load_preset

    preset = load_preset("quick")
    settings = TrainSettings.load(preset, config, overrides)
    return train_model(data, folder, settings, stages=stages or STAGES, preset=preset, progress=False)


@pytest.fixture(scope="session")
def trained(tmp_path_factory):
    """A tiny skirt model trained on the simulator-free dataset: (root, dataset, the hrr-train
    arguments that train the same, for the tests of the command line)."""
    from hrr_garment.garment.templates import make_garment

    root = tmp_path_factory.mktemp("codespace")
    data = synthetic_dataset(root / "skirt.h5", make_garment("skirt", 300))
    (root / "cfg.yaml").write_text(TINY_TRAINING)
    result = train_tiny(data, root / "model", root / "cfg.yaml")
    assert set(result.reports) == {"autoencoder", "codespace", "subspace"} and result.auto.mode in (
        "hybrid",
        "residual",
        "detail",
    )
    args = ["--dataset", str(data), "--config", str(root / "cfg.yaml"), "-o", str(root / "model"), "--quiet"]
    return root, data, args


def current_copy(trained, folder: Path) -> tuple[Path, list[str]]:
    """A copy of the shared trained model in ``folder``, brought up to date with a ``--stage
    codespace`` re-run (other tests train the shared model on), and that re-run's arguments."""
    import shutil

    root, data, args = trained
    shutil.copytree(root / "model", folder)
    stage = [
        "--dataset",
        str(data),
        "--config",
        args[3],
        "--stage",
        "codespace",
        "-o",
        str(folder),
        "--quiet",
    ]
    train_tiny(data, folder, Path(args[3]), stages=("codespace",))
    return folder, stage


def authored(vertices: np.ndarray) -> np.ndarray:
    """As an artist might have it: centimetres, Z up, modelled around a pelvis at the origin."""
    from hrr_garment.motion.skeleton import REST_PELVIS_HEIGHT

    v = vertices.astype(np.float64) - [0.0, REST_PELVIS_HEIGHT, 0.0]
    return np.stack([v[:, 0], -v[:, 2], v[:, 1]], 1) * 100.0


@pytest.fixture(scope="session")
def artist_model(tmp_path_factory):
    """An artist's dress OBJ (no groups, centimetres, Z up) simulated with ``--fit --attached auto``
    (tiny preset, three 1 s clips) and a tiny model trained on it as models were before the motion
    memory and the expected-code regression:
    (dataset, model folder, what hrr-simulate printed)."""
    pytest.importorskip("newton", reason="the sim extra is not installed")
    import contextlib
    import io

    from hrr_garment.cli.simulate import main as simulate_main
    from hrr_garment.garment.obj import write_obj
    from hrr_garment.garment.templates import make_garment

    root = tmp_path_factory.mktemp("artist")
    dress = make_garment("dress", 300)
    obj = root / "artist_dress.obj"
    write_obj(obj, authored(dress.vertices), dress.faces)
    data = root / "artist.h5"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert (
            simulate_main(
                [
                    "--template",
                    str(obj),
                    "--fit",
                    "--attached",
                    "auto",
                    "--preset",
                    "tiny",
                    "--motions",
                    "walk",
                    "spin",
                    "walk",
                    "--seconds",
                    "1.0",
                    "--jobs",
                    "1",
                    "--quiet",
                    "-o",
                    str(data),
                ]
            )
            == 0
        )
    # as bundles written before the motion memory and the expected-code regression
    (root / "cfg.yaml").write_text(
        TINY_TRAINING.replace(
            "attention_heads: 2}",
            "attention_heads: 2, memory_seconds: [], resonator_hz: [], regression_code: argmax}",
        )
    )
    train_tiny(data, root / "model", root / "cfg.yaml")
    return data, root / "model", printed.getvalue()


@pytest.fixture(scope="session")
def paper_model(trained, tmp_path_factory):
    """``trained``'s autoencoder with a code space validated the paper's way (hrr-train --validation
    windows): the model folder."""
    import shutil

    root, data, _ = trained
    folder = tmp_path_factory.mktemp("paper") / "model"
    shutil.copytree(root / "model" / "autoencoder", folder / "autoencoder")
    train_tiny(
        data,
        folder,
        root / "cfg.yaml",
        stages=("codespace",),
        overrides={"codespace": {"train": {"validation": "windows"}}},
    )
    return folder


def squeezed_skirt(motion, narrower: float, on_body: bool = False):
    """The tiny skirt (300 vertices) in each frame of ``motion``, narrowed about its axis to
    ``narrower`` of its width, into the hips: (the skirt, the frames float64). ``on_body``: worn in
    the body frame (it moves with the pelvis); else where its template lies, for a body that stays
    near the origin (dance, idle)."""
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.motion.frame import from_body_frame

    skirt = make_garment("skirt", 300)
    rest = np.repeat(skirt.vertices[None], motion.num_frames, 0).astype(np.float64)
    if on_body:
        rest = from_body_frame(rest, motion)
    centre = rest[:, :, [0, 2]].mean(1, keepdims=True)
    squeezed = rest.copy()
    squeezed[..., [0, 2]] = centre + narrower * (rest[..., [0, 2]] - centre)
    return skirt, squeezed


def with_drawn_sampler(animator, *, history: int = 0):
    """``animator``'s model with a generative decoder of untrained weights, calibrated by hand (a
    pole, a temperature, departure scales): what the paths of the sample mode must agree on holds
    for any weights, and this one is built in milliseconds where training one takes a minute."""
    import dataclasses
    import math

    import torch

    from hrr_garment.inference.animator import Animator
    from hrr_garment.models.sampler import ClothSampler, SamplerSettings

    bundle = animator.bundle
    latent = math.prod(bundle.codespace.latent_shape)
    torch.manual_seed(0)
    settings = SamplerSettings(hidden=32, layers=1, steps=2, history=history)
    sampler = ClothSampler(settings, len(bundle.motion_stats.mean), latent)
    sampler.residual_scale.copy_(torch.rand(latent) + 0.5)
    sampler.noise_decay.fill_(0.8)
    sampler.temperature.fill_(0.7)
    return Animator(dataclasses.replace(bundle, sampler=sampler.eval()))


def three_clips() -> dict:
    """Three characters' clips (walk_curve, spin, walk; 0.8 s each) for a crowd test."""
    from hrr_garment.motion.synth import synthesize

    return {
        "a": synthesize("walk_curve", 0.8, seed=1),
        "b": synthesize("spin", 0.8, seed=2),
        "c": synthesize("walk", 0.8, seed=3),
    }


def assert_crowd_streams_as_alone(crowd, clips: dict, alone: dict, atol: float = 1e-4) -> None:
    """Every frame of ``crowd`` (native or on a torch device) pushed all ``clips`` at once as an
    engine's poses, keyed, equals each character's ``alone`` frames (T, V, 3) within ``atol`` metres."""
    from hrr_garment.motion.poses import motion_to_poses

    poses = {k: motion_to_poses(m) for k, m in clips.items()}
    for frame in range(next(iter(clips.values())).num_frames):
        rotations = np.stack([p[0][frame] for p in poses.values()])
        out = crowd.push(rotations, np.stack([p[1][frame] for p in poses.values()]), list(clips))
        for row, k in enumerate(clips):
            assert np.abs(out[row] - alone[k][frame]).max() <= atol, (k, frame)
