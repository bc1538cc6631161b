"""The subspace stage on the shared tiny model: the fast decoder it distils, its size on validation,
its place in the bundle, the runs that use it, and a bundle without it refusing it clearly."""

import json
import shutil

import numpy as np
import pytest
import torch

from hrr_garment.motion.synth import synthesize


def test_the_fast_decoder_is_distilled_from_the_full_one(trained):
    from hrr_garment.artifacts.bundle_loader import load_bundle
    from hrr_garment.data.dataset import GarmentDataset

    root, data, _ = trained
    bundle = load_bundle(root / "model")
    entry = bundle.manifest.subspace
    assert bundle.subspace is not None and bundle.subspace.components == entry.components
    errors = {int(k): v for k, v in entry.candidates_mm.items()}
    kept = entry.components  # the fewest within the tolerance, or else the most accurate
    within = [k for k in sorted(errors) if errors[k] <= entry.train["tolerance"] * entry.full_validation_mm]
    assert kept == (within[0] if within else min(errors, key=errors.get))
    ds = GarmentDataset(data)
    with np.load(root / "model" / "autoencoder" / "latents.npz") as f:
        z = np.concatenate([f[n] for n in ds.splits["train"]])
    z = torch.from_numpy(z.astype(np.float32))
    full, fast = bundle.autoencoder.inference_decoder()(z).numpy(), bundle.subspace(z).numpy()
    spread = np.linalg.norm(full - full.mean(0), axis=-1).mean()  # what the mean frame alone would miss
    assert np.linalg.norm(fast - full, axis=-1).mean() < 0.35 * spread
    from hrr_garment.models.subspace import SubspaceSettings
    from hrr_garment.train.subspace import SubspaceTrainSettings, run_subspace_stage

    again = run_subspace_stage(
        data,
        root / "model",
        SubspaceSettings(**entry.config),
        SubspaceTrainSettings(**entry.train),
        progress=False,
    )
    assert again.reused and again.metrics["components"] == kept  # a finished stage is not redone


def test_runs_take_the_fast_decoder_and_record_it(trained, tmp_path):
    from hrr_garment.cli.animate import main as animate_main
    from hrr_garment.data.animation_file import read_animation_h5
    from hrr_garment.inference.animator import Animator
    from hrr_garment.motion.io import save_motion

    root, _, _ = trained
    animator = Animator.load(root / "model")
    motion = synthesize("walk_curve", 1.0, seed=3)
    fast = animator.animate(motion, mode="regression", push_out=False, decoder="fast")
    full = animator.animate(motion, mode="regression", push_out=False)
    assert fast.settings["decoder"] == "fast" and full.settings["decoder"] == "full"
    assert 0 < np.abs(fast.vertices - full.vertices).max() < 0.2
    stream = animator.stream(
        mode="regression", decoder="fast"
    )  # streaming equals offline causal, with either decoder
    causal = animator.animate(motion, mode="regression", causal=True, decoder="fast").vertices
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - causal).max() <= 1e-5
    clip, out = tmp_path / "walk.npz", tmp_path / "out.h5"
    save_motion(motion, clip)
    assert animate_main([str(clip), "-o", str(out), "--model", str(root / "model"), "--decoder", "fast"]) == 0
    assert read_animation_h5(out).attrs["decoder"] == "fast"


def test_a_bundle_without_a_fast_decoder_refuses_it_by_name(trained, tmp_path):
    from hrr_garment.artifacts.bundle_loader import BundleError, load_bundle
    from hrr_garment.artifacts.manifest import content_hash
    from hrr_garment.inference.animator import Animator
    from tests.conftest import write_meta

    root, _, _ = trained
    folder = tmp_path / "model"
    shutil.copytree(
        root / "model", folder, ignore=shutil.ignore_patterns("autoencoder", "codebook", "subspace")
    )
    meta = json.loads((folder / "bundle.json").read_text())
    meta.pop("subspace")
    meta["files"].pop("subspace.safetensors")
    (folder / "subspace.safetensors").unlink()
    write_meta(folder, {**meta, "content_hash": content_hash(meta["files"])})
    animator = Animator(load_bundle(folder))
    assert animator.bundle.subspace is None
    with pytest.raises(BundleError, match="hrr-train --stage subspace"):
        animator.animate(synthesize("walk", 0.5, seed=1), decoder="fast")
    with pytest.raises(BundleError, match="the subspace push runs on"):
        animator.animate(synthesize("walk", 0.5, seed=1), push="subspace")
    # the torch step (ONNX export, a GPU crowd) takes the same settings and says the same
    with pytest.raises(BundleError, match="hrr-train --stage subspace"):
        animator.crowd(mode="regression", decoder="fast", device="cpu")
