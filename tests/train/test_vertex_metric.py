"""The code space's vertex loss (hrr_garment.train.vertex_metric): the first-order vertex error of
standardised latent errors, against the decoder itself."""

import numpy as np
import pytest
import torch

from hrr_garment.garment.templates import make_garment
from hrr_garment.models.fcmae import AutoencoderSettings, MeshAutoencoder
from hrr_garment.models.hierarchy import build_hierarchy
from hrr_garment.settings import SettingsError
from hrr_garment.train.codespace_losses import mean_square
from hrr_garment.train.codespace_settings import CodeSpaceTrainSettings
from hrr_garment.train.vertex_metric import VertexMetric, sample_frames


@pytest.fixture(scope="module")
def decoder_and_frames():
    skirt = make_garment("skirt", 200)
    torch.manual_seed(0)
    model = MeshAutoencoder(
        build_hierarchy(skirt.faces, skirt.num_vertices),
        AutoencoderSettings(channels=[8, 16]),
        skirt.vertices,
        scale=0.05,
    ).eval()
    frames = torch.randn(6, *model.latent_shape).numpy()
    std = np.random.default_rng(1).uniform(0.5, 2.0, frames.shape[1] * frames.shape[2]).astype(np.float32)
    return model, frames, std


def test_the_metric_is_the_decoders_first_order_vertex_error(decoder_and_frames):
    model, frames, std = decoder_and_frames
    metric = VertexMetric.of_decoder(model, frames, std, ridge=0.0, progress=False)
    size = metric.size
    rng = np.random.default_rng(2)
    errors = torch.as_tensor(rng.normal(size=(8, size)) * 1e-2, dtype=torch.float32)  # standardised
    z = torch.as_tensor(frames)
    with torch.no_grad():  # each error's squared vertex motion, averaged over the frames the metric averages
        moved = torch.stack(
            [
                (model.decode(z + (e * torch.as_tensor(std)).reshape(z.shape[1:])) - model.decode(z))
                .pow(2)
                .sum((1, 2))
                .mean()
                for e in errors
            ]
        ).double()
    predicted = torch.stack([metric(e[None]) for e in errors]).double()
    ratio = predicted / moved
    # one scale for every error (the metric's normalisation), to first order
    assert float(ratio.std() / ratio.mean()) < 0.02
    # and an isotropic unit error scores 1 a value, as the mean square does
    unit = torch.as_tensor(rng.normal(size=(4000, size)), dtype=torch.float32)
    assert float(metric(unit)) == pytest.approx(float(mean_square(unit)), rel=0.05)


def test_the_metric_weighs_what_moves_the_vertices(decoder_and_frames):
    model, frames, std = decoder_and_frames
    metric = VertexMetric.of_decoder(model, frames, std, ridge=0.0, progress=False)
    gram = (metric.factor @ metric.factor.T).double()
    weights = torch.diag(gram)

    # a latent value's weight is the squared vertex motion of its unit (standardised) change, averaged
    # over the frames: the most and the least weighted values compare as their vertex motions do
    def vertex_motion(d: int) -> float:
        step = torch.zeros(metric.size)
        step[d] = 1e-2
        with torch.no_grad():
            z = torch.as_tensor(frames)
            raw = (step * torch.as_tensor(std)).reshape(z.shape[1:])
            return float((model.decode(z + raw) - model.decode(z)).pow(2).sum((1, 2)).mean())

    high, low = int(weights.argmax()), int(weights.argmin())
    assert float(weights[high] / weights[low]) == pytest.approx(
        vertex_motion(high) / vertex_motion(low), rel=0.03
    )
    assert float(weights[high]) > 3 * float(weights[low])  # not the identity in disguise
    e = torch.randn(metric.size)
    assert float(metric(e[None])) == pytest.approx(
        float(e.double() @ gram @ e.double()) / metric.size, rel=1e-4
    )
    ridge = VertexMetric.of_decoder(model, frames, std, ridge=0.3, progress=False)
    assert float(ridge(e[None])) == pytest.approx(
        0.7 * float(metric(e[None])) + 0.3 * float(e.pow(2).mean()), rel=1e-4
    )


def test_frames_are_sampled_seeded_and_settings_checked():
    frames = np.arange(100)[:, None]
    assert np.array_equal(sample_frames(frames, 10, seed=3), sample_frames(frames, 10, seed=3))
    assert len(np.unique(sample_frames(frames, 10))) == 10 and len(sample_frames(frames[:5], 10)) == 5
    with pytest.raises(SettingsError, match="latent_loss must be one of standardised, vertex"):
        CodeSpaceTrainSettings(latent_loss="vertices")
    with pytest.raises(SettingsError, match="vertex_ridge"):
        CodeSpaceTrainSettings(vertex_ridge=1.5)


def test_the_code_space_trains_on_either_latent_loss(trained, tmp_path):
    """codespace.train.latent_loss vertex (the real-motion presets') trains with the decoder's vertex
    error under another stage key than the default's plain mean square."""
    import json
    import shutil

    from hrr_garment.cli.train import main as train_main

    root, data, args = trained
    shutil.copytree(root / "model", tmp_path / "model")
    config = (
        (root / "cfg.yaml")
        .read_text()
        .replace("patience: 5, max_minutes: null}", "patience: 5, max_minutes: null, latent_loss: vertex}")
    )
    assert "latent_loss: vertex" in config
    (tmp_path / "cfg.yaml").write_text(config)
    before = json.loads((tmp_path / "model" / "codebook" / "report.json").read_text())
    stage = [
        "--dataset",
        str(data),
        "--config",
        str(tmp_path / "cfg.yaml"),
        "--stage",
        "codespace",
        "-o",
        str(tmp_path / "model"),
        "--quiet",
    ]
    assert train_main(stage) == 0
    after = json.loads((tmp_path / "model" / "codebook" / "report.json").read_text())
    assert before["training"]["config"]["latent_loss"] == "standardised"
    assert after["key"] != before["key"] and after["training"]["config"]["latent_loss"] == "vertex"
    logged = [
        json.loads(line) for line in (tmp_path / "model" / "codebook" / "log.jsonl").read_text().splitlines()
    ]
    assert len(logged) == after["training"]["epoch"] and all(np.isfinite(r["val_regress"]) for r in logged)
    assert np.isfinite(after["validation_mm"]["regression"])
