"""Code space: quantiser, entropy, windows, curriculum switch, retrieval database, bundle, hrr-train."""

import json
import math

import numpy as np
import pytest
import torch
from conftest import TINY_TRAINING, synthetic_dataset

from hrr_garment.artifacts.database import CodeDatabase, code_similarity, pack_codes
from hrr_garment.data.windows import build_windows
from hrr_garment.models.quantizer import GumbelQuantizer, group_entropy
from hrr_garment.train.codespace_training import PlateauDetector


@pytest.mark.parametrize("groups,classes,dim", [(4, 8, 3), (16, 2, 1), (64, 8, 8)])
def test_hard_codes_are_one_hot_and_gradients_flow_straight_through(groups, classes, dim):
    torch.manual_seed(0)
    q = GumbelQuantizer(groups, classes, dim).train()
    logits = torch.randn(5, groups * classes, requires_grad=True)
    codes, emb = q(logits, temperature=0.7)
    assert codes.shape == (5, groups, classes) and emb.shape == (5, groups * dim)
    assert torch.equal(codes.detach().sum(-1), torch.ones(5, groups))
    assert set(codes.detach().unique().tolist()) <= {0.0, 1.0}
    (emb * torch.randn_like(emb)).sum().backward()
    assert logits.grad is not None and torch.isfinite(logits.grad).all() and logits.grad.abs().sum() > 0
    assert q.embedding.grad is not None and q.embedding.grad.abs().sum() > 0
    q.eval()
    hard, _ = q(logits)
    assert torch.equal(hard.argmax(-1), q.split(logits).argmax(-1))  # eval: deterministic argmax


@pytest.mark.parametrize("classes", [2, 8, 16])
def test_entropy_of_one_hot_is_zero_and_of_uniform_is_log_k(classes):
    one_hot = torch.full((3, 5, classes), -1e4)
    one_hot[..., 1] = 0.0
    assert torch.allclose(group_entropy(one_hot), torch.zeros(3), atol=1e-6)
    assert torch.allclose(group_entropy(torch.zeros(3, 5, classes)), torch.full((3,), math.log(classes)), atol=1e-6)


def test_usage_counts_dead_classes_and_perplexity():
    q = GumbelQuantizer(2, 4, 1)
    usage = q.usage(torch.tensor([[0, 1], [1, 1], [2, 1], [3, 1]]))
    assert usage.dead == 3 and usage.total == 8  # group 1 only ever uses class 1
    assert usage.perplexity == pytest.approx((4 + 1) / 2)


def test_curriculum_switches_once_when_the_loss_plateaus():
    loss = [1.0 / (1 + e) for e in range(10)] + [0.0909] * 20  # falls, then flat from epoch 10
    detector = PlateauDetector(patience=5, delta=0.01)
    fired = [e for e, v in enumerate(loss) if detector.update(v)]
    assert fired == [15]  # last improvement at epoch 10 (0.1 -> 0.0909), then five flat epochs; only once


def test_decoding_only_the_last_frame_equals_the_full_window():
    from hrr_garment.models.codespace import CodeSpace, CodeSpaceConfig

    torch.manual_seed(0)
    cs = CodeSpace(CodeSpaceConfig(window=5, groups=4, classes=8, embedding_dim=3, hidden=32, motion_hidden=16), 124, (6, 8))
    embedding = torch.randn(7, cs.quantizer.embedding_size)
    with torch.no_grad():
        assert torch.allclose(cs.decode(embedding, last_frame=True), cs.decode(embedding)[:, -1:], atol=1e-6)


@pytest.mark.parametrize("window,hidden,heads,latent", [(10, 32, 2, (6, 8)), (7, 48, 3, (5, 3)), (12, 64, 4, (9, 8))])
@pytest.mark.parametrize("regression,last_frame,code", [(True, True, "expected"), (True, False, "expected"),
                                                        (False, True, "expected"), (True, True, "argmax")])
def test_native_window_step_equals_pytorch_and_is_batch_invariant(window, hidden, heads, latent, regression, last_frame,
                                                                    code):
    from hrr_garment.models.codes import WindowCodes
    from hrr_garment.models.codespace import CodeSpace, CodeSpaceConfig
    from hrr_garment.models.native_codes import native_window_codes

    torch.manual_seed(window)
    cfg = CodeSpaceConfig(window=window, groups=6, classes=5, embedding_dim=3, hidden=40, motion_hidden=hidden,
                          attention_heads=heads, regression_code=code)
    cs = CodeSpace(cfg, 124, latent).eval()
    native = native_window_codes(cs, regression, last_frame)
    if native is None:
        pytest.skip("no C compiler: the native kernels are unavailable")
    windows = torch.randn(9, window, 124)
    with torch.no_grad():
        want = WindowCodes(cs, regression, last_frame)(windows)
    got = native(windows)
    assert torch.allclose(got[0], want[0], atol=1e-5) and torch.equal(got[1], want[1])
    assert got[2].shape == want[2].shape and torch.allclose(got[2], want[2], atol=1e-5)
    one = native(windows[4:5])  # a stream's single window: the same bits as inside a batch
    assert all(torch.equal(a, b[4:5]) for a, b in zip(one[:2], got[:2]))
    assert not regression or torch.equal(one[2], got[2][4:5])


def test_the_expected_code_is_the_mean_embedding_under_each_groups_softmax():
    from hrr_garment.models.codes import regression_embedding
    from hrr_garment.models.codespace import CodeSpace, CodeSpaceConfig
    from hrr_garment.settings import SettingsError

    cs = {code: CodeSpace(CodeSpaceConfig(window=4, groups=3, classes=5, embedding_dim=2, hidden=8, motion_hidden=8,
                                          attention_heads=2, regression_code=code), 124, (2, 2)) for code in ("expected", "argmax")}
    cs["argmax"].quantizer.embedding.data = cs["expected"].quantizer.embedding.data
    table = cs["expected"].quantizer.embedding.detach()  # (G, K, D)
    with torch.no_grad():
        uniform = regression_embedding(cs["expected"], torch.zeros(1, 3, 5))
        assert torch.allclose(uniform.reshape(3, 2), table.mean(1), atol=1e-6)  # every class equally likely: the mean
        peaked = torch.full((1, 3, 5), -50.0)
        peaked[0, [0, 1, 2], [4, 0, 2]] = 50.0  # certain codes: both kinds give the same classes' embeddings
        assert torch.allclose(regression_embedding(cs["expected"], peaked), regression_embedding(cs["argmax"], peaked), atol=1e-6)
        logits = torch.randn(2, 3, 5)
        weights = torch.softmax(logits, -1)
        assert torch.allclose(regression_embedding(cs["expected"], logits).reshape(2, 3, 2),
                              torch.einsum("bgk,gkd->bgd", weights, table), atol=1e-6)
    with pytest.raises(SettingsError, match="regression_code"):
        CodeSpaceConfig(regression_code="mode")
    with pytest.raises(SettingsError, match="code space model: resonator damping"):
        CodeSpaceConfig(resonator_hz=(1.0,), resonator_damping=1.5)


def test_windows_cover_every_start_frame():
    feats = {"a": np.arange(12 * 2, dtype=np.float32).reshape(12, 2), "b": np.zeros((9, 2), np.float32)}
    lat = {"a": np.arange(12 * 3 * 2, dtype=np.float32).reshape(12, 3, 2), "b": np.zeros((9, 3, 2), np.float32)}
    w = build_windows(feats, lat, ["a", "b"], 10)
    assert len(w) == 3  # b is shorter than a window
    assert w.motion.shape == (3, 10, 2) and w.latents.shape == (3, 10, 3, 2)
    assert len(w.motion.frames) == 12  # each frame once
    for i in range(3):
        assert np.array_equal(w.motion[i], feats["a"][i:i + 10]) and np.array_equal(w.latents[i], lat["a"][i:i + 10])
    assert w.start.tolist() == [0, 1, 2] and w.sequence.tolist() == [0, 0, 0]


@pytest.mark.parametrize("seed", [0, 1])
def test_split_windows_partitions_the_windows_nine_to_one(seed):
    from hrr_garment.data.windows import split_windows

    feats = {n: np.random.default_rng(i).normal(size=(40, 2)).astype(np.float32) for i, n in enumerate("abc")}
    lat = {n: np.zeros((40, 3, 2), np.float32) for n in "abc"}
    every = build_windows(feats, lat, ["a", "b", "c"], 10)
    train, val = split_windows(every, 0.1, seed)
    assert len(val) == round(0.1 * len(every)) and len(train) + len(val) == len(every)
    pairs = lambda w: {(int(q), int(s)) for q, s in zip(w.sequence, w.start)}  # noqa: E731
    assert pairs(train) | pairs(val) == pairs(every) and not pairs(train) & pairs(val)
    for i in range(len(val)):  # each window keeps its own frames and source
        assert np.array_equal(val.motion[i], feats["abc"[val.sequence[i]]][val.start[i]:val.start[i] + 10])
    again = split_windows(every, 0.1, seed)[1]
    assert pairs(again) == pairs(val) and pairs(split_windows(every, 0.1, seed + 7)[1]) != pairs(val)
    with pytest.raises(ValueError):
        split_windows(every, 1.0)


def test_the_paper_protocol_validates_on_a_tenth_of_the_training_clips_windows(trained, paper_model):
    """hrr-train --validation windows: the training and validation clips' windows split 9:1, the
    database holds the nine tenths, tau is calibrated on the tenth, and the bundle says so."""
    from hrr_garment.artifacts.bundle import load_bundle
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.data.dataset import GarmentDataset

    root, data, args = trained
    report = json.loads((paper_model / "codebook" / "report.json").read_text())
    clips = json.loads((root / "model" / "codebook" / "report.json").read_text())
    ds = GarmentDataset(data)
    every = sum(max(ds.frames[n] - 9, 0) for n in ds.splits["train"] + ds.splits["val"])
    assert report["windows"]["val"] == round(0.1 * every) and report["windows"]["train"] + report["windows"]["val"] == every
    assert report["key"] != clips["key"]
    bundle = load_bundle(paper_model)
    assert bundle.meta["validation"] == "windows" and load_bundle(root / "model").meta["validation"] == "clips"
    assert len(bundle.database) == report["windows"]["train"]
    assert set(bundle.database.names) == set(ds.splits["train"] + ds.splits["val"])
    with pytest.raises(SystemExit):
        train_main([*args[:-1], "--validation", "folds"])


@pytest.fixture
def database(rng):
    n, groups, classes = 300, 32, 8
    codes = rng.integers(0, classes, (n, groups))
    return CodeDatabase(codes, rng.normal(size=(n, 4, 3, 2)).astype(np.float32), np.arange(n) // 100,
                        np.arange(n) % 100, ["s0", "s1", "s2"], classes)


def test_database_returns_the_exact_match_for_a_training_window(database):
    idx, sim = database.search(database.codes[[5, 150, 299]])
    assert idx.tolist() == [5, 150, 299] and np.allclose(sim, 1.0)


def test_hamming_search_equals_cosine_on_one_hot_codes(database, rng):
    queries = rng.integers(0, 8, (40, 32))
    queries[:10] = database.codes[:10]
    queries[:10, :5] = (queries[:10, :5] + 1) % 8  # near misses
    idx, sim = database.search(queries)
    onehot = lambda c: np.eye(8)[c].reshape(len(c), -1) / math.sqrt(c.shape[1])  # noqa: E731
    cosine = onehot(queries) @ onehot(database.codes).T
    assert np.allclose(sim, cosine.max(1)) and np.allclose(cosine[np.arange(40), idx], cosine.max(1))
    assert np.allclose(code_similarity(queries, database.codes), cosine)
    assert pack_codes(queries, 8).shape == (40, 32)


def test_search_can_exclude_the_query_sequence(database):
    idx, _ = database.search(database.codes[[5, 150]], exclude=np.array([0, 1]))
    assert database.sequence[idx[0]] != 0 and database.sequence[idx[1]] != 1


def test_hrr_train_writes_a_bundle_that_reproduces_its_validation_numbers(trained):
    from hrr_garment.artifacts.bundle import load_bundle
    from hrr_garment.train.calibrate import evaluate_bundle

    root, data, _ = trained
    report = json.loads((root / "model" / "codebook" / "report.json").read_text())
    log = [json.loads(line) for line in (root / "model" / "codebook" / "log.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in log] == [1, 2, 3, 4] and {"val_agreement", "val_perplexity", "val_dead_classes"} <= set(log[0])
    bundle = load_bundle(root / "model")
    again = evaluate_bundle(bundle, data)
    for mode in ("hybrid", "regression", "retrieval", "autoencoder", "retrieval_usage"):
        assert again[mode] == report["validation_mm"][mode], mode
    assert report["validation_mm"]["hybrid"] <= min(report["validation_mm"]["regression"], report["validation_mm"]["retrieval"])
    assert len(bundle.database) == report["windows"]["train"]
    from hrr_garment.data.dataset import GarmentDataset

    groups = GarmentDataset(data).template.groups  # kept in the bundle: evaluation measures the hem's swing
    assert set(groups) <= set(bundle.template.groups) and np.array_equal(bundle.template.groups["hem"], groups["hem"])


def test_calibration_on_a_window_sample_is_the_sample_of_the_full_errors(trained):
    """max_windows keeps evenly spaced windows: their errors are exactly those windows' full errors."""
    from hrr_garment.artifacts.bundle import load_bundle
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.data.windows import dataset_features
    from hrr_garment.train.autoencoder import body_frames
    from hrr_garment.train.calibrate import evaluate_modes

    root, data, _ = trained
    bundle, ds = load_bundle(root / "model"), GarmentDataset(data)
    names = ds.splits["val"]
    args = (bundle.codespace, bundle.autoencoder, bundle.motion_stats, bundle.latent_stats, bundle.database,
            dataset_features(ds, names, bundle.codespace.config.memory), {n: body_frames(ds, [n]) for n in names})
    full = evaluate_modes(*args, refine_steps=0, refine_lr=0.0, max_windows=None)
    sample = evaluate_modes(*args, refine_steps=0, refine_lr=0.0, max_windows=7)
    keep = np.linspace(0, len(full.regression) - 1, 7).round().astype(int)
    assert len(full.regression) > 7 and len(sample.regression) == 7
    for field in ("regression", "retrieval", "autoencoder", "entropy"):
        np.testing.assert_allclose(getattr(sample, field), getattr(full, field)[keep], rtol=1e-5, atol=1e-4)


def test_the_code_space_anneals_its_learning_rate_over_the_run_and_keeps_its_best_epoch(trained):
    """Cosine from learning_rate to lr_final x it over the run's epochs (tiny config: 4 epochs of
    1e-3, lr_final 0.01), and the bundle holds the epoch with the best validation regression."""
    import json

    root = trained[0]
    log = [json.loads(line) for line in (root / "model" / "codebook" / "log.jsonl").read_text().splitlines()]
    rates = [r["learning_rate"] for r in log]
    assert len(rates) == 4 and all(a > b for a, b in zip(rates, rates[1:]))
    assert rates[0] < 1e-3 and rates[-1] < 1e-3 * 0.05  # logged at each epoch's last batch, just short of the end
    report = json.loads((root / "model" / "codebook" / "report.json").read_text())["training"]
    best = min(range(4), key=lambda i: log[i]["val_regress"])
    assert report["best_epoch"] == best + 1 and report["final"]["regress"] == pytest.approx(log[best]["val_regress"], rel=1e-5)


def test_the_old_codebook_names_still_work_with_a_deprecation_message(trained, capsys):
    from hrr_garment.cli.train import main as train_main

    root, data, args = trained
    old = (root / "cfg.yaml").read_text().replace("\ncodespace:", "\ncodebook:")
    (root / "cfg_old.yaml").write_text(old)
    args_old = [a if a != str(root / "cfg.yaml") else str(root / "cfg_old.yaml") for a in args]
    capsys.readouterr()
    assert train_main([*args_old, "--stage", "codebook"]) == 0
    out, err = capsys.readouterr()
    assert "code space:" in out and "(reused)" in out  # the same stage, settings and outputs
    assert "--stage codebook is now --stage codespace" in err and "'codebook' is now called 'codespace'" in err


def test_rerun_resumes_the_code_space_and_skips_finished_stages(trained, capsys):
    from hrr_garment.cli.train import main as train_main

    root, data, args = trained
    capsys.readouterr()
    assert train_main(args) == 0
    assert "(reused)" in capsys.readouterr().out
    longer = (root / "cfg.yaml").read_text().replace("epochs: 4", "epochs: 5")
    (root / "cfg5.yaml").write_text(longer)
    args5 = [a if a != str(root / "cfg.yaml") else str(root / "cfg5.yaml") for a in args]
    assert train_main(args5) == 0
    log = [json.loads(line) for line in (root / "model" / "codebook" / "log.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in log] == [1, 2, 3, 4, 5]  # continued from epoch 4's checkpoint, one more epoch


def test_a_new_encoding_retrains_the_code_space(trained, tmp_path):
    """Changing only the refinement re-encodes the same autoencoder weights; the code space (and
    the bundle's database) trained on the old latents must not be reused."""
    import shutil

    from hrr_garment.artifacts.bundle import load_bundle
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.train.calibrate import evaluate_bundle

    root, data, args = trained
    shutil.copytree(root / "model", tmp_path / "model")
    config = (root / "cfg.yaml").read_text().replace("max_minutes: null}", "max_minutes: null, refine_steps: 3}", 1)
    (tmp_path / "cfg.yaml").write_text(config)
    before = json.loads((tmp_path / "model" / "codebook" / "report.json").read_text())
    assert train_main(["--dataset", str(data), "--config", str(tmp_path / "cfg.yaml"), "-o", str(tmp_path / "model"), "--quiet"]) == 0
    autoencoder = json.loads((tmp_path / "model" / "autoencoder" / "report.json").read_text())
    after = json.loads((tmp_path / "model" / "codebook" / "report.json").read_text())
    assert autoencoder["extra"]["refine_steps"] == 3 and autoencoder["epochs"] == 3  # re-encoded, not retrained
    assert after["key"] != before["key"] and not after.get("reused")
    # the floor is scored with the stage's encoding (3 steps, not the default 10: the same weights
    # refined for 3 steps land elsewhere), here and from the bundle in a fresh load
    assert after["validation_mm"]["autoencoder"] != before["validation_mm"]["autoencoder"]
    again = evaluate_bundle(load_bundle(tmp_path / "model"), data)
    assert again["autoencoder"] == after["validation_mm"]["autoencoder"]


def test_corrupt_bundle_and_wrong_garment_are_explained(trained, tmp_path):
    import shutil

    from hrr_garment.artifacts.bundle import BundleError, load_bundle
    from hrr_garment.data.dataset import DatasetError
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.train.calibrate import evaluate_bundle

    root, _, _ = trained
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    dress = synthetic_dataset(tmp_path / "dress.h5", make_garment("dress", 300))
    with pytest.raises(DatasetError, match="dress dataset"):
        evaluate_bundle(load_bundle(copy), dress)
    db = copy / "database.safetensors"
    db.write_bytes(db.read_bytes()[:-100])
    with pytest.raises(BundleError, match="database.safetensors.*corrupt or truncated"):
        load_bundle(copy)
    (copy / "bundle.json").unlink()
    with pytest.raises(BundleError, match="no bundle.json"):
        load_bundle(copy)


def test_too_few_sequences_to_split_is_refused(tmp_path, capsys):
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.data.dataset import GarmentDataset, write_dataset
    from hrr_garment.garment.templates import make_garment

    full = GarmentDataset(synthetic_dataset(tmp_path / "all.h5", make_garment("skirt", 300)))
    records = [full.sequence("walk_000")]
    data = write_dataset(tmp_path / "one.h5", full.template, records, {"train": ["walk_000"], "val": [], "test": []})
    (tmp_path / "cfg.yaml").write_text(TINY_TRAINING)
    out = tmp_path / "model"
    assert train_main(["--dataset", str(data), "--config", str(tmp_path / "cfg.yaml"), "-o", str(out), "--quiet"]) == 2
    assert "one.h5" in capsys.readouterr().err
    assert not (out / "bundle.json").exists()


def _retamper_hashes(folder, meta, names):
    """Re-hash ``names`` in ``meta`` as a careful tamperer would (so only the check under test can fire)."""
    import hashlib

    for name in names:
        meta["files"][name] = hashlib.sha256((folder / name).read_bytes()).hexdigest()
    meta["content_hash"] = hashlib.sha256(json.dumps(meta["files"], sort_keys=True).encode()).hexdigest()[:16]


def _nan_weights(folder, meta):
    from safetensors.torch import load_file, save_file

    path = folder / "decoder.safetensors"
    state = load_file(str(path))
    key = next(k for k, v in state.items() if v.is_floating_point())
    state[key] = state[key].clone().fill_(float("nan"))
    save_file(state, str(path))
    _retamper_hashes(folder, meta, ["decoder.safetensors"])


def _nan_stats(folder, meta):
    from safetensors.numpy import load_file, save_file

    path = folder / "stats.safetensors"
    arrays = load_file(str(path))
    arrays["latent_std"] = arrays["latent_std"].copy()
    arrays["latent_std"][0] = np.nan
    save_file(arrays, str(path))
    _retamper_hashes(folder, meta, ["stats.safetensors"])


def _escape(folder, meta):
    outside = folder.parent / "secret.txt"
    outside.write_text("not part of the model")
    meta["files"]["../secret.txt"] = ""
    _retamper_hashes(folder, meta, ["../secret.txt"])


def _bad_template_faces(folder, meta):
    """Found by tools/fuzz.py: template faces that index past the vertices, hashes redone."""
    from safetensors.numpy import load_file, save_file

    path = folder / "template.safetensors"
    arrays = load_file(str(path))
    arrays["faces"] = arrays["faces"].copy()
    arrays["faces"][0, 0] = -587202263
    save_file(arrays, str(path))
    _retamper_hashes(folder, meta, ["template.safetensors"])


TAMPERS = {  # name: (edit of bundle.json's dict, or of the folder and dict; the error it must raise)
    "files deleted": (lambda f, m: m.pop("files"), "no valid 'files'"),
    "one file unlisted": (lambda f, m: m["files"].pop("decoder.safetensors"), r"does not list \['decoder.safetensors'\]"),
    "files as a list": (lambda f, m: m.update(files=list(m["files"])), "no valid 'files'"),
    "path escape": (_escape, "directly in the bundle folder"),
    "content_hash edited": (lambda f, m: m.update(content_hash="0" * 16), "content_hash .* was edited"),
    "tau a string": (lambda f, m: m.update(tau="abc"), "'tau' must be a finite number"),
    "tau NaN": (lambda f, m: m.update(tau=float("nan")), "'tau' must be a finite number"),
    "tau negative": (lambda f, m: m.update(tau=-1.0), "'tau' must be a finite number"),
    "garment a list": (lambda f, m: m.update(garment=["skirt"]), "'garment' must be a name"),
    "database missing": (lambda f, m: m.pop("database"), "lacks its 'database' section"),
    "auto an unknown mode": (lambda f, m: m.update(auto={"mode": "retrieval"}), "'auto' must hold a 'mode' of"),
    "auto a string": (lambda f, m: m.update(auto="detail"), "'auto' must hold a 'mode' of"),
    "detail base unknown": (lambda f, m: m.update(auto={"mode": "detail", "detail_base": "retrieval"}),
                            "'detail_base' must be one of regression, residual"),
    "detail strength negative": (lambda f, m: m.update(auto={"mode": "detail", "detail_strength": -0.5}),
                                 "'detail_strength' must be a number in"),
    "detail strength NaN": (lambda f, m: m.update(auto={"mode": "detail", "detail_strength": float("nan")}),
                            "'detail_strength' must be a number in"),
    "NaN weights, hashes redone": (_nan_weights, "decoder.safetensors: non-finite weights"),
    "NaN statistics, hashes redone": (_nan_stats, "stats.safetensors: non-finite values"),
    "template faces out of range, hashes redone": (_bad_template_faces, "template.safetensors: face indices must lie"),
}


@pytest.mark.parametrize("case", list(TAMPERS))
def test_a_tampered_bundle_is_refused(trained, tmp_path, case):
    import shutil

    from hrr_garment.artifacts.bundle import BundleError, load_bundle

    root, _, _ = trained
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    meta = json.loads((copy / "bundle.json").read_text())
    edit, message = TAMPERS[case]
    edit(copy, meta)
    (copy / "bundle.json").write_text(json.dumps(meta))
    with pytest.raises(BundleError, match=message):
        load_bundle(copy)


def test_bundle_json_that_is_not_an_object_or_not_text_is_refused(trained, tmp_path):
    import shutil

    from hrr_garment.artifacts.bundle import BundleError, load_bundle

    root, _, _ = trained
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    (copy / "bundle.json").write_text("[1, 2]")
    with pytest.raises(BundleError, match="format_version None"):
        load_bundle(copy)
    (copy / "bundle.json").write_bytes(b'{"garment": "\xff\xfe"}')
    with pytest.raises(BundleError, match="unreadable"):
        load_bundle(copy)


def test_a_dataset_no_stage_can_finish_is_refused_before_training(tmp_path, capsys):
    """Found by tools/fuzz.py: without a validation split the autoencoder trained for minutes and
    left its stage behind before the code space refused the dataset."""
    import h5py

    from hrr_garment.cli.train import main as train_main
    from hrr_garment.garment.templates import make_garment

    data = synthetic_dataset(tmp_path / "skirt.h5", make_garment("skirt", 300))
    with h5py.File(data, "r+") as f:
        del f["splits/val"]
    (tmp_path / "cfg.yaml").write_text(TINY_TRAINING)
    out = tmp_path / "model"
    assert train_main(["--dataset", str(data), "--config", str(tmp_path / "cfg.yaml"), "-o", str(out), "--quiet"]) == 2
    assert "needs at least one training and one validation sequence" in capsys.readouterr().err
    assert not out.exists()


def test_a_bundle_written_before_the_expected_code_regresses_from_the_argmax(trained, tmp_path):
    import shutil

    from hrr_garment.artifacts.bundle import load_bundle

    root, _, _ = trained
    assert load_bundle(root / "model").codespace.config.regression_code == "expected"  # the default now
    shutil.copytree(root / "model", tmp_path / "old")
    meta = json.loads((tmp_path / "old" / "bundle.json").read_text())
    del meta["codespace"]["config"]["regression_code"]
    (tmp_path / "old" / "bundle.json").write_text(json.dumps(meta))
    assert load_bundle(tmp_path / "old").codespace.config.regression_code == "argmax"
