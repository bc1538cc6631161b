"""Training the mesh autoencoder on a garment dataset, then encoding every frame to latents.

Vertices are expressed in the body's heading frame (origin under the pelvis, Z along its
heading), where a garment's shape depends on the pose but not on where the body is or which way it
faces. Loss: L1 on vertex positions plus ``laplacian`` x L1 on uniform Laplacian coordinates
(keeps the surface smooth between vertices). Adam with a cosine learning-rate schedule over the
run (:func:`set_learning_rate`), early stopping on the validation split's per-vertex error, a
checkpoint after every epoch (a re-run resumes from it), seeded. Every frame is then encoded, each
latent refined by a few gradient steps through the decoder (``MeshAutoencoder.fit_latents``); the
report's errors are those of the refined latents, the encoder's own in ``extra``.

Outputs in the model folder (``autoencoder/``): ``config.json``, ``model.pt`` (the best weights,
a plain state dict), ``checkpoint.pt`` (for resuming), ``latents.npz`` (per sequence (T, N, 8)),
``report.json``.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from ..data.dataset import GarmentDataset
from ..errors import InputError
from ..garment.mesh import mirror_map
from ..io_utils import atomic_path, atomic_write_text
from ..models.fcmae import AutoencoderConfig, MeshAutoencoder
from ..models.hierarchy import cached_hierarchy
from ..settings import from_settings
from .checkpoint import keep_if_best, load_checkpoint, save_checkpoint
from ..motion.frame import FRAME_VERSION, to_body_frame


@dataclass(frozen=True)
class TrainConfig:
    epochs: int = 300
    batch_size: int = 32
    learning_rate: float = 8e-3
    lr_final: float = 0.01  # the cosine schedule's last learning rate, as a fraction of the first
    laplacian: float = 0.2
    patience: int = 30  # epochs without a better validation error before stopping (see early_stop)
    max_minutes: float | None = None  # wall-clock budget for this run
    seed: int = 0
    threads: int | None = None
    device: str = "cpu"  # torch device to train on ("cuda" on a GPU machine); the outputs are the same files
    mirror: bool = True  # add left-right mirrored training frames when the template is symmetric
    refine_steps: int = 10  # Adam steps on each encoded latent through the decoder (0: the encoder's latents)
    refine_lr: float = 0.03

    @classmethod
    def from_dict(cls, values: dict) -> "TrainConfig":
        return from_settings(cls, values, "training")


def refine_settings(values: dict) -> dict:
    """The encoding's settings (``fit_latents``' steps and rate) from a train config as a dict: a
    run's own, its saved config.json, or a bundle's record. Missing ones (files from before they
    were recorded) are the defaults."""
    default = TrainConfig()
    return {"refine_steps": int(values.get("refine_steps", default.refine_steps)),
            "refine_lr": float(values.get("refine_lr", default.refine_lr))}


@dataclass
class AutoencoderReport:
    folder: Path
    epochs: int
    best_epoch: int
    val_pve_mm: float
    test_pve_mm: float
    train_pve_mm: float
    minutes: float
    latent_shape: tuple[int, int]
    sizes: tuple[int, ...]
    extra: dict = field(default_factory=dict)


def body_frames(ds: GarmentDataset, names: list[str]) -> np.ndarray:
    """All frames of ``names`` in each frame's body frame (:mod:`..motion.frame`), (N, V, 3) float32."""
    out = []
    for name in names:
        rec = ds.sequence(name)
        out.append(to_body_frame(rec.garment.astype(np.float64), rec.motion).astype(np.float32))
    return np.concatenate(out) if out else np.zeros((0, ds.template.num_vertices, 3), np.float32)


def laplacian_operator(index: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Sparse (V, V) uniform Laplacian from 1-ring lists whose slot 0 is the vertex itself:
    each vertex minus the mean of its neighbours."""
    v = index.shape[0]
    count = mask[:, 1:].sum(1).clamp(min=1)
    rows = torch.arange(v).unsqueeze(1).expand_as(index[:, 1:])[mask[:, 1:] > 0]
    cols = index[:, 1:][mask[:, 1:] > 0]
    vals = -(1.0 / count).unsqueeze(1).expand_as(index[:, 1:])[mask[:, 1:] > 0]
    i = torch.cat([torch.stack([rows, cols]), torch.arange(v).repeat(2, 1)], 1)
    return torch.sparse_coo_tensor(i, torch.cat([vals, torch.ones(v)]), (v, v), check_invariants=True).coalesce()


def apply_laplacian(op: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """(B, V, 3) -> (V, B * 3) Laplacian coordinates (vertex-major: a sparse matmul)."""
    return torch.sparse.mm(op, x.transpose(0, 1).reshape(x.shape[1], -1))


def pve_mm(model: MeshAutoencoder, frames: np.ndarray, latents: np.ndarray | None = None, batch: int = 64) -> float:
    """Mean per-vertex Euclidean error (mm) of reconstructing ``frames``: through the encoder, or
    by decoding the given ``latents`` (one per frame)."""
    if len(frames) == 0:
        return float("nan")
    total = 0.0
    device = model.template.device
    with torch.no_grad():
        for i in range(0, len(frames), batch):
            x = torch.from_numpy(frames[i:i + batch]).to(device)
            y = model(x) if latents is None else model.decode(torch.from_numpy(latents[i:i + batch]).to(device))
            total += float((y - x).norm(dim=-1).mean(1).sum())
    return 1000.0 * total / len(frames)


def training_device(name: str) -> torch.device:
    """The torch device called ``name``, or a clear error when this machine has none such."""
    try:
        device = torch.device(name)
    except RuntimeError as exc:
        raise InputError("--device", f"{name!r} is not a torch device ({exc})") from None
    if device.type == "cuda" and not torch.cuda.is_available():
        raise InputError("--device", "CUDA was asked for, but this torch build or machine has no CUDA device")
    return device


def run_progress(epoch: float, epochs: int, elapsed_s: float, max_minutes: float | None) -> float:
    """How far the run is, 0 to 1: by epochs, or by the wall-clock budget when that ends first."""
    by_time = 0.0 if max_minutes is None else elapsed_s / (60.0 * max_minutes)
    return min(1.0, max(epoch / max(epochs, 1), by_time))


def epoch_fits(now: float, deadline: float | None, epoch_s: float | None) -> bool:
    """Whether another epoch, as long as the last one (``epoch_s``; None before the first), ends
    by ``deadline``. The budget is then a cap on training, not the last moment an epoch may
    start: on a slow hour of this 2-core machine a quick epoch takes 23 s, and starting one just
    before the deadline took the stage to 10.02 minutes with the encoding."""
    if deadline is None:
        return True
    return now + (epoch_s or 0.0) <= deadline


def early_stop(stale_epochs: int, patience: int, progress: float) -> bool:
    """Stop after ``patience`` epochs without a better validation error, but only in the last fifth
    of the run, once the rate is below a tenth of its start. Before that the validation error can
    stall for dozens of epochs and then fall as the rate anneals: on the full dress (GPU) two runs
    stopped at epochs 53 and 58 with 4.8 and 4.7 mm, where the same settings run to the end of
    the schedule reached 4.0 mm."""
    return stale_epochs >= patience and progress >= 0.8


def set_learning_rate(optimizer: torch.optim.Optimizer, config: TrainConfig, progress: float) -> float:
    """Cosine from ``learning_rate`` down to ``lr_final`` x it at the end of the run. Tied to the
    run's progress rather than to epochs, so a budgeted run (the quick preset) still ends with a
    small learning rate: with a per-epoch decay it stopped while the rate was high and the
    weights still noisy, and a long run froze long before its end."""
    lo = config.learning_rate * config.lr_final
    lr = lo + 0.5 * (config.learning_rate - lo) * (1.0 + math.cos(math.pi * progress))  # a float: the checkpoint holds it
    for group in optimizer.param_groups:
        group["lr"] = lr
    return lr


def _key(*parts) -> str:
    return hashlib.sha1(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:16]


def train_autoencoder(dataset: str | Path, folder: str | Path, model_config: AutoencoderConfig = AutoencoderConfig(),
                      train_config: TrainConfig = TrainConfig(), cache_dir: Path | None = None,
                      progress: bool = True) -> AutoencoderReport:
    """Train (or resume), keep the best weights, encode every sequence. See the module docstring."""
    t_start = time.perf_counter()
    device = training_device(train_config.device)  # before anything is written
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(train_config.seed)
    if train_config.threads:
        torch.set_num_threads(train_config.threads)
    ds = GarmentDataset(dataset)
    splits = ds.splits
    train = body_frames(ds, splits["train"])
    val = body_frames(ds, splits.get("val", []))
    test = body_frames(ds, splits.get("test", []))
    template = ds.template.vertices.astype(np.float32)
    perm = mirror_map(template) if train_config.mirror else None
    simulated = len(train)  # the training frames before the mirrored ones are added
    if perm is not None:  # heading frame: x is the body's left-right axis
        train = np.concatenate([train, train[:, perm] * np.array([-1, 1, 1], np.float32)])
    scale = float(np.std(train - template)) if len(train) else 0.1
    hierarchy = cached_hierarchy(ds.template.faces, ds.template.num_vertices, cache_dir, latent_fraction=model_config.latent_fraction,
                                 stride=model_config.stride, radius=model_config.radius, name=str(dataset))
    model = MeshAutoencoder(hierarchy, model_config, template, scale).to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=train_config.learning_rate)
    # the checkpoint's key leaves out what only the encoding uses: changing the refinement re-encodes
    # a finished run (its checkpoint is at the end of training) instead of training it again
    # the objective was L1 per coordinate before: those latents re-encode
    encoding = refine_settings(asdict(train_config)) | {"refine_objective": "vertex distance"}
    training = {k: v for k, v in asdict(train_config).items() if k not in encoding}
    training_key = _key(model_config.to_dict(), training | {"max_minutes": None, "threads": None, "device": None},
                        ds.garment, ds.template.num_vertices, splits, {"frame": FRAME_VERSION})
    key = _key(training_key, encoding)
    checkpoint = folder / "checkpoint.pt"
    report_path = folder / "report.json"
    if report_path.is_file() and (folder / "latents.npz").is_file() and (folder / "model.pt").is_file():
        done = json.loads(report_path.read_text())
        if done.get("key") == key:  # finished with these settings: nothing to redo
            done.pop("key")
            return AutoencoderReport(**{**done, "folder": folder, "latent_shape": tuple(done["latent_shape"]),
                                        "sizes": tuple(done["sizes"]), "extra": {**done.get("extra", {}), "reused": True}})
    state = {"epoch": 0, "best": float("inf"), "best_epoch": 0, "stale": 0, "elapsed_s": 0.0}
    best_weights = {k: v.clone() for k, v in model.state_dict().items()}
    state, best_weights = load_checkpoint(checkpoint, training_key, state, best_weights, model=model, optimizer=optimizer)
    conv0 = model.encoder[0].conv
    lap = laplacian_operator(conv0.index.cpu(), conv0.mask.cpu()).to(device)
    rng = np.random.default_rng(train_config.seed + state["epoch"])
    bar = tqdm(total=train_config.epochs, initial=state["epoch"], desc="autoencoder", unit="epoch", disable=not progress)
    # the wall-clock budget counts the time of earlier (interrupted) runs too
    started, spent = time.perf_counter(), state["elapsed_s"]
    deadline = None if train_config.max_minutes is None else started + 60 * train_config.max_minutes - spent

    def progress(epoch: float) -> float:
        return run_progress(epoch, train_config.epochs, spent + time.perf_counter() - started, train_config.max_minutes)

    epoch_s = None  # the last epoch's duration
    while state["epoch"] < train_config.epochs:
        if not epoch_fits(time.perf_counter(), deadline, epoch_s):
            break
        epoch_started = time.perf_counter()
        if early_stop(state["stale"], train_config.patience, progress(state["epoch"])):
            break
        model.train()
        order = rng.permutation(len(train))
        losses = []
        for i in range(0, len(order), train_config.batch_size):
            set_learning_rate(optimizer, train_config, progress(state["epoch"] + i / len(order)))
            x = torch.from_numpy(train[order[i:i + train_config.batch_size]]).to(device)
            y = model(x)
            loss = (y - x).abs().mean() + train_config.laplacian * (apply_laplacian(lap, y - x)).abs().mean()
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            losses.append(loss.item())
        model.eval()
        val_err = pve_mm(model, val if len(val) else train[:256])
        state["epoch"] += 1
        state["elapsed_s"] = spent + time.perf_counter() - started
        best_weights = keep_if_best(state, val_err, model, best_weights)
        save_checkpoint(checkpoint, training_key, state, best_weights, model=model, optimizer=optimizer)
        bar.set_postfix(loss=f"{np.mean(losses) * 1000:.2f}mm", val=f"{val_err:.2f}mm", best=f"{state['best']:.2f}mm")
        bar.update(1)
        epoch_s = time.perf_counter() - epoch_started
    bar.close()
    model.load_state_dict(best_weights)
    model.eval()
    # encoding (the refinement's decoder passes) runs on the training device, the rest on the CPU,
    # where inference will
    latents = encode_dataset(model, ds, folder / "latents.npz", train_config.refine_steps, train_config.refine_lr,
                             progress=not bar.disable)
    model.cpu()
    with atomic_path(folder / "model.pt") as tmp:
        torch.save(model.state_dict(), tmp)
    atomic_write_text(folder / "config.json", json.dumps({"model": model_config.to_dict(), "train": asdict(train_config),
                                                          "dataset": str(dataset), "garment": ds.garment,
                                                          "vertices": ds.template.num_vertices, "scale": scale,
                                                          "sizes": list(hierarchy.sizes)}, indent=2))

    def refined_pve(split: str, frames: np.ndarray, every: int = 1) -> float:
        """``frames``: the split's frames in ``splits`` order, as ``latents`` holds them."""
        names = splits.get(split, [])
        if not names:
            return float("nan")
        return pve_mm(model, frames[::every], np.concatenate([latents[n] for n in names])[::every])

    report = AutoencoderReport(folder, state["epoch"], state["best_epoch"], refined_pve("val", val),
                               refined_pve("test", test), refined_pve("train", train[:simulated], every=4),
                               (time.perf_counter() - t_start) / 60, model.latent_shape,
                               hierarchy.sizes, {"refine_steps": train_config.refine_steps,
                                                 "encoder_only_mm": {"val": state["best"], "test": pve_mm(model, test)}})
    atomic_write_text(report_path, json.dumps({"key": key, **{k: (str(v) if isinstance(v, Path) else v)
                                                              for k, v in asdict(report).items()}}, indent=2))
    return report


def encode_dataset(model: MeshAutoencoder, ds: GarmentDataset, path: Path, refine_steps: int = 10,
                   refine_lr: float = 0.03, progress: bool = True) -> dict[str, np.ndarray]:
    """Latents (T, N, 8) float32 of every sequence (``fit_latents``), written to ``path`` as one
    npz entry per sequence name, and returned."""
    latents = {}
    for name in tqdm(ds.names, desc="encoding", unit="sequence", disable=not progress):
        frames = torch.from_numpy(body_frames(ds, [name])).to(model.template.device)
        latents[name] = model.fit_latents(frames, refine_steps, refine_lr).cpu().numpy()
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **latents)
    return latents


def load_autoencoder(folder: str | Path, faces: np.ndarray, cache_dir: Path | None = None) -> MeshAutoencoder:
    """The trained model of ``folder`` (weights only; no pickled objects are loaded)."""
    folder = Path(folder)
    meta = json.loads((folder / "config.json").read_text())
    config = AutoencoderConfig.from_dict(meta["model"])
    hierarchy = cached_hierarchy(faces, meta["vertices"], cache_dir, latent_fraction=config.latent_fraction,
                                 stride=config.stride, radius=config.radius)
    model = MeshAutoencoder(hierarchy, config)
    state = torch.load(folder / "model.pt", map_location="cpu", weights_only=True)
    # files from before the neighbour lists stopped being saved (they are rebuilt from the template)
    state = {k: v for k, v in state.items() if not k.endswith((".index", ".mask"))}
    model.load_state_dict(state)
    return model.eval()
