"""Mesh autoencoder: sampling hierarchy, layers, fast path, overfitting, latent interpolation."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from hrr_garment.garment.mesh import GarmentError
from hrr_garment.garment.templates import make_garment
from hrr_garment.models.fcmae import AutoencoderSettings, MeshAutoencoder
from hrr_garment.models.hierarchy import build_hierarchy, cached_hierarchy
from hrr_garment.native.decoder import bf16_bits, bf16_pairs
from hrr_garment.sim.quality import edge_strain


@pytest.fixture(scope="module")
def skirt():
    return make_garment("skirt", 300)


@pytest.fixture(scope="module")
def hierarchy(skirt):
    return build_hierarchy(skirt.faces, skirt.num_vertices)


def test_hierarchy_levels_cover_every_vertex(hierarchy, skirt):
    h = hierarchy
    assert h.sizes[0] == skirt.num_vertices and all(a > b for a, b in zip(h.sizes, h.sizes[1:]))
    assert 0.005 * skirt.num_vertices <= h.sizes[-1] <= 0.05 * skirt.num_vertices + 4
    for level in range(h.levels - 1):
        down, up = h.down[level], h.up[level]
        assert down.index.shape[0] == h.sizes[level + 1] and up.index.shape[0] == h.sizes[level]
        covered = np.zeros(h.sizes[level], bool)
        covered[down.index[down.mask]] = True
        assert covered.all()  # every vertex is pooled by some centre
        assert up.mask.any(1).all()  # ... so unpooling reaches every vertex
        # Each centre pools itself; unpooling is the transpose of pooling.
        centres = h.centres[level]
        assert all(c in down.index[i][down.mask[i]] for i, c in enumerate(centres))
        pairs_down = {(int(v), i) for i in range(len(down.index)) for v in down.index[i][down.mask[i]]}
        pairs_up = {(v, int(c)) for v in range(len(up.index)) for c in up.index[v][up.mask[v]]}
        assert pairs_down == pairs_up
    for level, conv in enumerate(h.conv):
        assert conv.index.shape[0] == h.sizes[level] and (conv.index[:, 0] == np.arange(h.sizes[level])).all()


def test_hierarchy_is_deterministic_and_cached(tmp_path, skirt, hierarchy):
    again = cached_hierarchy(skirt.faces, skirt.num_vertices, tmp_path)
    from_cache = cached_hierarchy(skirt.faces, skirt.num_vertices, tmp_path)
    assert len(list(tmp_path.glob("hierarchy-*.npz"))) == 1
    for h in (again, from_cache):
        assert h.sizes == hierarchy.sizes
        for a, b in zip(h.down, hierarchy.down):
            assert np.array_equal(a.index, b.index) and np.array_equal(a.mask, b.mask)


def test_latent_level_keeps_a_minimum_of_nodes():
    from hrr_garment.models.fcmae import AutoencoderSettings

    dress = make_garment("dress", 1000)
    one_percent = build_hierarchy(dress.faces, dress.num_vertices)
    floored = build_hierarchy(dress.faces, dress.num_vertices, min_latent_nodes=64)
    assert one_percent.sizes[-1] < 32  # 1 % of 1,046 vertices: the ~18-node level
    assert floored.sizes == one_percent.sizes[:-1] and 48 <= floored.sizes[-1] <= 96  # the level nearest 64
    # a model saved before the option existed loads with the hierarchy it was trained on
    assert AutoencoderSettings.from_dict({"latent_fraction": 0.01}).min_latent_nodes == 4
    assert AutoencoderSettings().hierarchy_options()["min_latent_nodes"] == 4


def test_disconnected_template_is_rejected():
    with pytest.raises(GarmentError, match="one connected mesh"):  # two separate triangles
        build_hierarchy(np.array([[0, 1, 2], [3, 4, 5]]), 6, name="two.obj")


def _model(hierarchy, skirt, seed=0, **cfg):
    torch.manual_seed(seed)
    return MeshAutoencoder(hierarchy, AutoencoderSettings(**cfg), skirt.vertices, scale=0.05)


def test_shapes_and_normalised_pooling(hierarchy, skirt):
    model = _model(hierarchy, skirt)
    x = torch.as_tensor(skirt.vertices)[None].repeat(3, 1, 1)
    z = model.encode(x)
    assert z.shape == (3, hierarchy.sizes[-1], 8) and model.decode(z).shape == x.shape
    # Intermediate shapes: each encoder block lands on its level.
    h = x.transpose(0, 1)
    for block, size in zip(model.encoder, [hierarchy.sizes[0], *hierarchy.sizes[1:], hierarchy.sizes[-1]]):
        h = block(h)
        assert h.shape[:2] == (size, 3)
    for block in [*model.encoder, *model.decoder]:
        if block.residual.neighbours:
            with torch.no_grad():
                block.residual.logits.normal_()
            w = block.residual.weights()
            assert (w >= 0).all() and torch.allclose(w.sum(1), torch.ones(len(w)))
            assert (w[block.residual.mask == 0] == 0).all()


@pytest.mark.native
@pytest.mark.parametrize("native", [True, False])
@pytest.mark.parametrize("batch", [1, 5, 19])
def test_inference_decoder_equals_training_path(hierarchy, skirt, batch, native):
    model = _model(hierarchy, skirt, seed=3)
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.1 * torch.randn_like(p))  # not the initial values
    fast = model.inference_decoder(native=native)
    if native and not fast.native:
        pytest.skip("no C compiler")
    z = torch.randn(batch, *model.latent_shape)  # 1: the single-frame path; 19: tiles plus a remainder
    with torch.no_grad():
        first = fast(z)
        assert (first - model.decode(z)).abs().max() <= 1e-5
        fast(torch.randn_like(z))  # reused scratch buffers must not leak into, or alias, earlier results
        assert torch.equal(fast(z), first) and (first - model.decode(z)).abs().max() <= 1e-5


def _amx_decoder(model):
    fast = model.inference_decoder()
    if not fast.native or not fast.lib.hrr_amx_ready():
        pytest.skip("no AMX (bfloat16 decoding) on this CPU")
    return model.inference_decoder(precision="bfloat16")


@pytest.mark.native
def test_bfloat16_bits_round_as_pytorch_and_pair_rows():
    x = torch.randn(1000) * torch.logspace(-6, 6, 1000)
    x[:4] = torch.tensor([1.0 + 2**-8, 1.0 + 3 * 2**-8, -0.0, 65504.0])  # ties round to even both ways
    assert np.array_equal(bf16_bits(x.numpy()), x.bfloat16().view(torch.int16).numpy().view(np.uint16))
    m = np.arange(2 * 4 * 3, dtype=np.float32).reshape(
        2, 4, 3
    )  # (matrices, cin, width): small integers are exact
    pairs = bf16_pairs(m)
    assert pairs.shape == (2, 2, 3, 2)
    back = torch.from_numpy(pairs.astype(np.int16)).view(torch.bfloat16).float().numpy()
    assert np.array_equal(back[:, 1, 2], m[:, 2:4, 2])  # pair row p, column n: input rows 2p and 2p + 1


@pytest.mark.native
@pytest.mark.parametrize("batch", [6, 19, 40])
def test_bfloat16_decoder_stays_within_its_rounding(hierarchy, skirt, batch):
    model = _model(hierarchy, skirt, seed=3)
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.1 * torch.randn_like(p))
    fast = _amx_decoder(model)
    z = torch.randn(batch, *model.latent_shape)  # 6: one padded tile of 16; 19: two tiles; 40: a pair and one
    with torch.no_grad():
        exact = model.decode(z)
        first = fast(z)
        fast(
            torch.randn(batch + 9, *model.latent_shape)
        )  # other frames in the kept buffers, padding included
        assert torch.equal(fast(z), first)
    # end to end: 5 blocks of 8-significant-bit rounding (2^-9 relative), sums in float32
    shape = (exact - model.template).norm(dim=-1)
    error = (first - exact).norm(dim=-1)
    assert error.mean() <= 1e-2 * shape.mean() and error.max() <= 5e-2 * shape.max()


def _bf16(a):
    return torch.from_numpy(np.ascontiguousarray(a, np.float32)).bfloat16().double().numpy()


@pytest.mark.native
def test_bfloat16_block_equals_its_rounded_reference(hierarchy, skirt):
    """Each AMX block against the same block in float64 from bfloat16-rounded inputs, kernels and
    residual map: what is left is float32 summation order."""
    model = _model(hierarchy, skirt, seed=3)
    fast = _amx_decoder(model)
    x = torch.randn(model.latent_shape[0], 19, model.latent_shape[1]).numpy()
    for i, block in enumerate(fast.native_blocks):
        last = i == len(fast.native_blocks) - 1
        xb = np.zeros((len(x), 32, x.shape[2]), np.uint16)
        xb[:, :19] = bf16_bits(x)
        got = block.call_bf16(fast.lib, xb, 1, last)[:, :19, : block.cout]
        got = (
            torch.from_numpy(got.astype(np.int16)).view(torch.bfloat16).double().numpy() if not last else got
        )
        xr = _bf16(x)
        kernel, proj = (
            _bf16(block.kernel[..., : block.cout]),
            _bf16(np.eye(block.cin, block.cout) if block.proj is None else block.proj[:, : block.cout]),
        )
        want = np.empty((block.vertices, 19, block.cout))
        for v in range(block.vertices):
            j = slice(block.offsets[v], block.offsets[v + 1])
            rows = xr[block.nbr[j]]  # (S, B, cin)
            y = np.einsum("sbc,sco->bo", rows, kernel[j]) + block.bias[: block.cout]
            projected = rows @ proj if block.pool is not None else xr[v] @ proj
            residual = (
                np.einsum("s,sbo->bo", block.pool[j], projected) if block.pool is not None else projected
            )
            act = np.where(y > 0, y, np.expm1(np.minimum(y, 0))) if block.elu else y
            want[v] = block.a * act + block.b * residual
        tolerance = 1e-5 * np.abs(want).max() if last else 2**-8 * np.abs(want) + 1e-6 * np.abs(want).max()
        assert (np.abs(got - want) <= tolerance).all(), f"block {i}"
        x = got.astype(np.float32)


@pytest.mark.native
def test_bfloat16_without_amx_is_refused_clearly(hierarchy, skirt, monkeypatch):
    model = _model(hierarchy, skirt, seed=3)
    fast = model.inference_decoder()
    if not fast.native:
        pytest.skip("no C compiler")
    monkeypatch.setattr(fast.lib, "hrr_amx_ready", lambda: 0)
    with pytest.raises(RuntimeError, match="AMX"):
        model.inference_decoder(precision="bfloat16")
    with pytest.raises(ValueError, match="precision"):
        model.inference_decoder(precision="float16")


def _two_frames(skirt):
    """The skirt swung 8 cm forward and 8 cm back, more towards the hem (smooth shapes)."""
    v = skirt.vertices.astype(np.float32)
    depth = np.clip((v[:, 1].max() - v[:, 1]) / np.ptp(v[:, 1]), 0, 1) ** 2
    frames = []
    for sign in (1.0, -1.0):
        f = v.copy()
        f[:, 2] += sign * 0.08 * depth
        f[:, 1] += 0.02 * depth * np.cos(np.arctan2(v[:, 0], v[:, 2]))
        frames.append(f)
    return torch.as_tensor(np.stack(frames))


@pytest.fixture(scope="module")
def overfit(hierarchy, skirt):
    model = _model(hierarchy, skirt, seed=1)
    x = _two_frames(skirt)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    sched = torch.optim.lr_scheduler.ExponentialLR(opt, 0.995)
    for _ in range(600):
        loss = (model(x) - x).abs().mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
    return model.eval(), x


@pytest.mark.slow
def test_tiny_model_overfits_to_half_a_millimetre(overfit):
    model, x = overfit
    with torch.no_grad():
        err = (model(x) - x).norm(dim=-1).mean(1)
    assert err.max() < 0.0005, f"per-vertex error {err.tolist()} m"


@pytest.mark.slow
def test_latent_interpolation_has_no_spikes(overfit, skirt):
    model, x = overfit
    edges = skirt.edges()
    with torch.no_grad():
        z = model.encode(x)
        ends = model.decode(z).numpy()
        mids = model.decode(
            torch.stack([(1 - t) * z[0] + t * z[1] for t in np.linspace(0.1, 0.9, 9)])
        ).numpy()
    bound = edge_strain(ends, skirt.vertices, edges).max() + 0.05
    assert edge_strain(mids, skirt.vertices, edges).max() <= bound


@pytest.mark.slow
def test_fitted_latents_beat_the_encoder_and_ignore_batching(overfit, skirt):
    model, x = overfit
    rest = torch.as_tensor(skirt.vertices, dtype=torch.float32)
    unseen = torch.cat([rest + 0.5 * (x - rest), rest + 1.3 * (x[:1] - rest)])  # swings it was not trained on
    weights = {k: v.clone() for k, v in model.state_dict().items()}
    fitted = model.fit_latents(unseen, steps=10)
    with torch.no_grad():
        encoded = model.encode(unseen)
        err_encoded = (model.decode(encoded) - unseen).norm(dim=-1).mean(1)
        err_fitted = (model.decode(fitted) - unseen).norm(dim=-1).mean(1)
    assert err_fitted.mean() < 0.8 * err_encoded.mean(), (err_fitted, err_encoded)
    assert all(torch.equal(v, model.state_dict()[k]) for k, v in weights.items())  # the weights stay fixed
    assert torch.equal(model.fit_latents(unseen, steps=0), encoded)
    one_by_one = torch.cat([model.fit_latents(unseen[i : i + 1], steps=10) for i in range(len(unseen))])
    assert torch.allclose(
        one_by_one, fitted, atol=1e-3
    )  # a frame's latent does not depend on its batch (up to rounding)


@pytest.mark.slow
def test_training_resumes_and_encodes_every_sequence(tmp_path, skirt, monkeypatch):
    from hrr_garment.data.dataset import SequenceRecord, write_dataset
    from hrr_garment.motion.rotations import rotation_about_y, yaw_of
    from hrr_garment.motion.synth import synthesize
    from hrr_garment.train import autoencoder as ae
    from hrr_garment.train import checkpoint
    from hrr_garment.train.autoencoder_settings import AutoencoderTrainSettings

    frames = _two_frames(skirt).numpy()

    def record(kind: str, seed: int, seconds: float = 0.4) -> SequenceRecord:
        motion = synthesize(kind, seconds, seed=seed)  # 30 fps; garment placed in the motion's heading frame
        yaw = yaw_of(motion.global_rotations[:, 0])
        t = np.linspace(0, 1, motion.num_frames)[:, None, None]
        local = (1 - t) * frames[0] + t * frames[1]
        world = (
            np.einsum("tij,tnj->tni", rotation_about_y(yaw), local)
            + (motion.root_translation * [1, 0, 1])[:, None]
        )
        return SequenceRecord(f"{kind}_000", world.astype(np.float32), motion)

    records = [record(kind, i) for i, kind in enumerate(("walk", "spin", "idle"))]  # 12 frames each
    splits = {"train": ["walk_000"], "val": ["spin_000"], "test": ["idle_000"]}
    data = write_dataset(tmp_path / "d.h5", skirt, records, splits)
    cfg = AutoencoderTrainSettings(
        epochs=3, batch_size=8, patience=10, refine_steps=0
    )  # counts the training's Adam steps only

    # kill the first run after its second checkpoint
    saves = []
    save = checkpoint.save_checkpoint

    def save_then_die(*args, **kwargs):
        save(*args, **kwargs)
        saves.append(1)
        if len(saves) == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(checkpoint, "save_checkpoint", save_then_die)
    with pytest.raises(KeyboardInterrupt):
        ae.train_autoencoder(data, tmp_path / "ae", train_config=cfg, progress=False)
    assert not (tmp_path / "ae" / "model.pt").exists()  # nothing final written by the killed run

    trained = []
    step = torch.optim.Adam.step

    def counting_step(self, *args, **kwargs):
        trained.append(1)
        return step(self, *args, **kwargs)

    monkeypatch.setattr(checkpoint, "save_checkpoint", save)
    monkeypatch.setattr(torch.optim.Adam, "step", counting_step)
    again = ae.train_autoencoder(data, tmp_path / "ae", train_config=cfg, progress=False)
    assert again.epochs == 3
    assert (
        len(trained) == 3
    )  # one epoch left after the checkpoint at epoch 2: 12 frames + mirrored, 3 batches of 8
    with np.load(tmp_path / "ae" / "latents.npz") as z:
        assert sorted(z.files) == ["idle_000", "spin_000", "walk_000"]
        assert z["walk_000"].shape == (12, *again.metrics["latent_shape"])
    trained.clear()
    assert ae.train_autoencoder(data, tmp_path / "ae", train_config=cfg, progress=False).reused
    assert not trained  # finished with these settings: nothing is redone
    # another refinement re-encodes the finished run without training it again
    with np.load(tmp_path / "ae" / "latents.npz") as z:
        plain = z["spin_000"].copy()
    saves.clear()
    monkeypatch.setattr(checkpoint, "save_checkpoint", save_then_die)
    refined = ae.train_autoencoder(
        data, tmp_path / "ae", train_config=replace(cfg, refine_steps=3), progress=False
    )
    assert not saves and refined.metrics["extra"]["refine_steps"] == 3 and not refined.reused
    with np.load(tmp_path / "ae" / "latents.npz") as z:
        assert not np.allclose(z["spin_000"], plain)
    # the same names in a dataset made again, one sequence longer: its latents, the weights kept
    again = write_dataset(tmp_path / "d2.h5", skirt, [record("walk", 0, 0.8), *records[1:]], splits)
    encoded = ae.train_autoencoder(
        again, tmp_path / "ae", train_config=replace(cfg, refine_steps=3), progress=False
    )
    assert not encoded.reused and not saves  # no checkpoint written: encoded, not trained
    with np.load(tmp_path / "ae" / "latents.npz") as z:
        assert z["walk_000"].shape == (24, *encoded.metrics["latent_shape"])
    model = ae.load_autoencoder(tmp_path / "ae", skirt.faces)
    x = torch.as_tensor(frames[:1])
    with torch.no_grad():
        assert model(x).shape == x.shape


def test_learning_rate_anneals_over_the_run_by_epochs_or_budget():
    from hrr_garment.train.autoencoder_settings import AutoencoderTrainSettings
    from hrr_garment.train.schedule import early_stop, run_progress, set_learning_rate

    cfg = AutoencoderTrainSettings(learning_rate=0.01, lr_final=0.02)
    opt = torch.optim.Adam([torch.nn.Parameter(torch.zeros(1))], lr=1.0)
    rates = [set_learning_rate(opt, cfg, p) for p in np.linspace(0, 1, 11)]
    assert rates[0] == pytest.approx(0.01) and rates[-1] == pytest.approx(0.0002)
    assert rates[5] == pytest.approx(0.5 * (0.01 + 0.0002))  # cosine: halfway at half the run
    assert np.all(np.diff(rates) < 0) and opt.param_groups[0]["lr"] == rates[-1]
    assert run_progress(10, 100, 0.0, None) == pytest.approx(0.1)
    assert run_progress(10, 100, 150.0, 5.0) == pytest.approx(0.5)  # half the budget gone: that wins
    assert run_progress(90, 100, 150.0, 5.0) == pytest.approx(0.9)
    assert run_progress(0, 100, 1e6, 5.0) == 1.0  # an overrun budget stays at the end
    assert not early_stop(30, 30, 0.5)  # stalled while the rate is high: keep going
    assert early_stop(30, 30, 0.85) and not early_stop(29, 30, 0.85)


def test_the_budget_caps_training_instead_of_being_the_last_start():
    from hrr_garment.train.schedule import epoch_fits

    assert epoch_fits(100.0, None, 50.0)  # no budget
    assert epoch_fits(99.0, 100.0, None)  # the first epoch always runs
    assert epoch_fits(70.0, 100.0, 30.0) and not epoch_fits(71.0, 100.0, 30.0)  # 71 + 30 would overrun
    assert not epoch_fits(101.0, 100.0, None)


def test_training_device_is_checked_before_anything_is_written(tmp_path):
    from hrr_garment.errors import InputError
    from hrr_garment.train.autoencoder import train_autoencoder
    from hrr_garment.train.autoencoder_settings import AutoencoderTrainSettings
    from hrr_garment.train.schedule import training_device

    assert training_device("cpu") == torch.device("cpu")
    with pytest.raises(InputError, match="not a torch device"):
        training_device("gpu0")
    if not torch.cuda.is_available():
        with pytest.raises(InputError, match="no CUDA device"):
            train_autoencoder(
                tmp_path / "missing.h5", tmp_path / "ae", train_config=AutoencoderTrainSettings(device="cuda")
            )
        assert not (tmp_path / "ae").exists()


@pytest.mark.slow
def test_mirrored_datasets_are_not_mirrored_again_and_epochs_are_bounded(tmp_path, skirt, monkeypatch):
    from hrr_garment.data.dataset import GarmentDataset, SequenceRecord, write_dataset
    from hrr_garment.motion.synth import synthesize
    from hrr_garment.train import autoencoder as ae
    from hrr_garment.train.autoencoder_settings import AutoencoderTrainSettings
    from hrr_garment.train.training_frames import training_frames

    motion = synthesize("idle", 0.8, seed=0)  # 24 frames
    frames = np.repeat(skirt.vertices[None], motion.num_frames, 0).astype(np.float32)
    records = [SequenceRecord(n, frames, motion) for n in ("a", "b", "c")]
    splits = {"train": ["a"], "val": ["b"], "test": ["c"]}
    plain = write_dataset(tmp_path / "plain.h5", skirt, records, splits)
    mirrored = write_dataset(
        tmp_path / "mirrored.h5", skirt, records, splits, info={"augmentation": {"mirror": True}}
    )
    assert len(training_frames(GarmentDataset(plain), mirror=True).train) == 48  # mirrored here
    assert (
        len(training_frames(GarmentDataset(mirrored), mirror=True).train) == 24
    )  # mirrored by the simulator
    steps = []
    step = torch.optim.Adam.step

    def counting_step(self, *args, **kwargs):
        steps.append(1)
        return step(self, *args, **kwargs)

    monkeypatch.setattr(torch.optim.Adam, "step", counting_step)
    cfg = AutoencoderTrainSettings(epochs=2, batch_size=4, refine_steps=0, frames_per_epoch=8)
    ae.train_autoencoder(plain, tmp_path / "ae", train_config=cfg, progress=False)
    assert len(steps) == 4  # two epochs of 8 of the 48 frames, in batches of 4
