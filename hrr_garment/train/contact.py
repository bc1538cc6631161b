"""The contact phase of the code-space stage: the decoder taught to keep the garment out of the body.

The regression is a conditional mean, and where the cloth lies on the body (a bodice on the chest
and shoulders, a skirt on the thighs mid-stride) an error of a centimetre puts it inside. The
latent losses cannot see the body, and a heavy body's tighter fit makes it worse: the model across
bodies put 5.0 % of the vertices more than 5 mm inside a held-out heavy body before the push-out,
where the simulations of the same clips have 0.8 % (docs/results.md). This phase shows the decoder
the body.

After the main training, ``contact_steps`` Adam steps on the decoder alone (the encoders, and so
the codes and the retrieval database, stay as trained), each on a batch of training windows: the
regression path's latent loss as in training, plus ``contact_weight`` times the mean depth (in mm)
by which decoded vertices fall inside the body grown by ``contact_margin_m`` (2 mm by default: a
clearance, so that a small error at run time stays outside). One random frame
of each window is decoded through the frozen mesh decoder: the depth needs vertices, and decoding
whole windows would cost some twenty times more for a gradient that neighbouring frames share.

The body is the one each sequence was simulated on, posed by its own motion and taken into its body
frame (:mod:`hrr_garment.motion.frame`): the mesh the viewer sees where the body has one (an anny
body, a fitted character: :attr:`~hrr_garment.garment.dressing.DressedBody.visible`, the signed
distance of :mod:`.skin_contact`), its capsules where it has not (the mannequin) or where
``contact_body`` is "capsules". Decoded frames get that body's rest offset added, as inference adds
it (:meth:`~hrr_garment.garment.dressing.DressedBody.offset`). The report says which bodies' skins
and which capsules the phase trained against and measured (``against``).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from ..data.dataset import DatasetError, GarmentDataset
from ..data.windows import WindowSet
from ..io_utils import atomic_path, strict_json
from ..models.codes import regression_embedding
from ..models.codespace import CodeSpace
from ..models.fcmae import MeshAutoencoder
from ..motion.frame import to_body_frame
from ..sim.quality import PENETRATION_DEPTH_M
from .codespace_losses import WindowTensors
from .codespace_settings import CodeSpaceTrainSettings
from .skin_contact import VisibleContacts

LEARNING_RATE = 1e-4  # a tenth of training's initial rate: the phase adjusts a trained decoder
BATCH = 64  # windows (and so decoded frames) a step
REPORT_WINDOWS = 512  # validation windows whose middle frame the report decodes before and after


@dataclass(frozen=True)
class BodyContacts:
    """Per stored frame of a :class:`~hrr_garment.data.windows.WindowSet` (row for row with its
    motion and latent frames): the capsules of the body the frame's sequence was simulated on,
    posed and in the body frame, and which body's rest offset its decoded garment stands on; and
    where bodies have a skin (``visible``), the joints' poses that pose it."""

    a: torch.Tensor  # (frames, C, 3) capsule end points
    b: torch.Tensor  # (frames, C, 3)
    body: torch.Tensor  # (frames,) int64 row of ``radii`` and ``offsets``
    radii: torch.Tensor  # (bodies, C) each body's capsule radii
    offsets: torch.Tensor  # (bodies, V, 3) each body's rest offset from the template
    names: tuple[str, ...] = ()  # each body's name
    visible: VisibleContacts | None = None  # the skins of the bodies that have one; None: capsules only

    @classmethod
    def of(cls, ds: GarmentDataset, windows: WindowSet, against: str = "visible") -> "BodyContacts":
        """``against``: "visible", each body's skin where it has one (its capsules where not: the
        mannequin); "capsules", the capsules of every body."""
        contacts = cls.of_sequences(ds, windows.names, against, min_frames=windows.motion.window)
        frames = len(windows.motion.frames)
        if len(contacts.body) != frames:
            raise ValueError(f"the windows store {frames} frames, their sequences have {len(contacts.body)}")
        return contacts

    @classmethod
    def of_sequences(
        cls, ds: GarmentDataset, names: list[str], against: str = "visible", *, min_frames: int = 1
    ) -> "BodyContacts":
        """Of every frame of the sequences ``names`` in turn, those shorter than ``min_frames`` left
        out (a window set stores none of their frames); ``against`` as :meth:`of`."""
        body_names = sorted({ds.body_name_of[n] for n in names})
        a, b, rows, motions = [], [], [], []
        for name in names:
            motion, body = ds.sequence(name).motion, ds.bodies[ds.body_name_of[name]].body
            if motion.num_frames < min_frames:
                continue
            ends = body.pose_motion(motion)
            if a and len(body.capsules) != a[0].shape[1]:
                raise DatasetError(
                    ds.path,
                    f"sequence {name!r} stands on a body of {len(body.capsules)} capsules, "
                    f"another on {a[0].shape[1]}: the contact phase needs one capsule set",
                )
            a.append(to_body_frame(ends[0], motion))
            b.append(to_body_frame(ends[1], motion))
            rows.append(np.full(len(ends[0]), body_names.index(ds.body_name_of[name])))
            motions.append(motion)
        radii = np.stack([ds.bodies[n].body.radii for n in body_names]).astype(np.float32)
        offsets = np.stack([ds.bodies[n].offset(ds.template) for n in body_names])
        skins = [
            (ds.bodies[n].visible if against == "visible" else None, ds.bodies[n].body) for n in body_names
        ]
        return cls(
            *(torch.from_numpy(np.concatenate(x).astype(np.float32)) for x in (a, b)),
            torch.from_numpy(np.concatenate(rows).astype(np.int64)),
            torch.from_numpy(radii),
            torch.from_numpy(offsets),
            names=tuple(body_names),
            visible=(
                VisibleContacts.of(motions, np.concatenate(rows), skins)
                if any(s is not None for s, _ in skins)
                else None
            ),
        )

    def distance(self, vertices: torch.Tensor, rows: torch.Tensor, reach_m: float = 0.0) -> torch.Tensor:
        """(n, V) signed distance of body-frame ``vertices`` (n, V, 3) of the stored frames ``rows``
        to their bodies, differentiable: to the skin where :attr:`visible` has one (exact wherever
        at most ``reach_m``, elsewhere a bound above it: :mod:`.skin_contact`), else the capsules."""
        body = self.body[rows]
        capsules = capsule_distance(vertices, self.a[rows], self.b[rows], self.radii[body])
        if self.visible is None:
            return capsules
        return self.visible.distance(vertices, rows, fallback=capsules, reach_m=reach_m)

    @property
    def against(self) -> dict[str, list[str]]:
        """Which bodies the distances are to: their skins ("visible") or their capsules."""
        skinned = self.visible.skinned if self.visible is not None else [False] * len(self.names)
        out = {"visible": [n for n, s in zip(self.names, skinned) if s]}
        out["capsules"] = [n for n, s in zip(self.names, skinned) if not s]
        return {k: v for k, v in out.items() if v}


def capsule_distance(
    points: torch.Tensor, a: torch.Tensor, b: torch.Tensor, radii: torch.Tensor
) -> torch.Tensor:
    """Signed distance (n, V) of points (n, V, 3) to each frame's union of capsules (ends a, b
    (n, C, 3), radii (n, C)); negative inside. Differentiable; the torch twin of
    :func:`~hrr_garment.body.capsules.capsule_signed_distance` (tested equal)."""
    axis = b - a
    rel = points[:, :, None] - a[:, None]  # (n, V, C, 3)
    s = ((rel * axis[:, None]).sum(-1) / (axis * axis).sum(-1).clamp_min(1e-12)[:, None]).clamp(0.0, 1.0)
    return ((rel - s[..., None] * axis[:, None]).norm(dim=-1) - radii[:, None]).min(-1).values


def _regression(model: CodeSpace, motion: torch.Tensor) -> torch.Tensor:
    """The regression path as inference runs it: (n, W, F) standardised motion -> (n, W, N, C)
    standardised latents; the motion encoder's output is a constant here (only the decoder learns)."""
    with torch.no_grad():
        logits = model.quantizer.split(model.motion_encoder(motion))
    return model.decode(regression_embedding(model, logits), condition=model.condition_of(motion))


@dataclass(frozen=True)
class ContactWindows:
    """Windows (:class:`~.codespace_losses.WindowTensors`) and their frames' bodies."""

    windows: WindowTensors
    contacts: BodyContacts


class FrameDecoder:
    """Standardised latents of stored frames -> their signed distance to the bodies they stand on."""

    def __init__(self, autoencoder: MeshAutoencoder, latent_stats):
        self.autoencoder = autoencoder
        self.mean = torch.from_numpy(np.asarray(latent_stats.mean, np.float32))
        self.std = torch.from_numpy(np.asarray(latent_stats.std, np.float32))

    def distance(
        self, latents: torch.Tensor, contacts: BodyContacts, rows: torch.Tensor, reach_m: float = 0.0
    ) -> torch.Tensor:
        """(n, N, C) standardised latents of the stored frames ``rows`` -> (n, V) signed distance of
        their decoded vertices, on their bodies' rest offsets, to their bodies
        (:meth:`BodyContacts.distance`)."""
        raw = latents.reshape(len(latents), -1) * self.std + self.mean
        vertices = self.autoencoder.decode(raw.reshape(latents.shape)) + contacts.offsets[contacts.body[rows]]
        return contacts.distance(vertices, rows, reach_m)


def evenly_spaced(count: int, most: int) -> torch.Tensor:
    """Up to ``most`` of the rows 0 .. ``count`` - 1, evenly spaced (what a phase's report measures)."""
    return torch.from_numpy(np.unique(np.linspace(0, count - 1, min(most, count)).astype(np.int64)))


def share_inside(distances: Iterable[torch.Tensor]) -> float:
    """The share of all the signed distances in ``distances`` more than 5 mm inside the body."""
    inside, total = 0.0, 0
    for d in distances:
        inside += float((d < -PENETRATION_DEPTH_M).sum())
        total += d.numel()
    return inside / total


def load_phase(path: Path, key: str, model: torch.nn.Module) -> dict | None:
    """A contact phase's result kept at ``path`` under ``key``: its weights loaded into ``model`` and
    its summary; None where there is none under that key."""
    if not path.is_file():
        return None
    saved = torch.load(path, map_location="cpu", weights_only=True)
    if saved.get("key") != key:
        return None
    model.load_state_dict(saved["weights"])
    return json.loads(saved["summary"])


def save_phase(path: Path, key: str, model: torch.nn.Module, *, summary: dict) -> None:
    """Keep a contact phase's result (``model``'s weights and ``summary``) at ``path`` under ``key``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        torch.save({"key": key, "weights": model.state_dict(), "summary": strict_json(summary)}, tmp)


@torch.no_grad()
def inside_fraction(
    model: CodeSpace, decoder: FrameDecoder, data: ContactWindows, count: int = REPORT_WINDOWS
) -> float:
    """The fraction of vertices more than 5 mm inside the body (the contacts' own: skin or capsules,
    :attr:`BodyContacts.against`) in the regression's middle frame of up to ``count`` of the
    windows, evenly spaced."""
    windows = data.windows
    if not len(windows):
        return float("nan")
    middle = windows.window // 2

    def distances(chunk: torch.Tensor) -> torch.Tensor:
        motion, _ = windows[chunk]
        return decoder.distance(
            _regression(model, motion)[:, middle], data.contacts, windows.first[chunk] + middle
        )

    return share_inside(distances(chunk) for chunk in evenly_spaced(len(windows), count).split(BATCH))


def teach_contact(
    model: CodeSpace,
    decoder: FrameDecoder,
    train: ContactWindows,
    *,
    val: ContactWindows | None,
    config: CodeSpaceTrainSettings,
    latent_loss: Callable[[torch.Tensor], torch.Tensor],
    checkpoint: tuple[Path, str],
    progress: bool = True,
) -> dict:
    """Run the phase (module docstring; ``config.contact_steps`` and ``contact_weight``) on
    ``model`` in place and return its summary, with the share of ``val``'s vertices inside the body
    before and after. The result is kept at ``checkpoint`` (path, key): a re-run with the same key
    loads it instead."""
    path, key = checkpoint
    if (kept := load_phase(path, key, model)) is not None:
        return kept
    decoder.autoencoder.requires_grad_(False)  # frozen: its weights' gradients would be computed for nothing
    model.eval()  # the decoder as inference runs it
    before = inside_fraction(model, decoder, val) if val is not None else float("nan")
    optimizer = torch.optim.Adam(model.decoder.parameters(), lr=LEARNING_RATE)
    gen = torch.Generator().manual_seed(config.seed)
    windows, started, depth_sum = train.windows, time.perf_counter(), 0.0
    for _ in tqdm(range(config.contact_steps), desc="contact", unit="step", disable=not progress):
        idx = torch.randint(0, len(windows), (min(BATCH, len(windows)),), generator=gen)
        motion, latents = windows[idx]
        pred = _regression(model, motion)
        frame = torch.randint(0, windows.window, (len(idx),), generator=gen)
        distance = decoder.distance(
            pred[torch.arange(len(idx)), frame],
            train.contacts,
            windows.first[idx] + frame,
            reach_m=config.contact_margin_m,  # the skin's answers are needed only this near
        )
        depth_mm = 1000.0 * torch.relu(config.contact_margin_m - distance).mean()
        loss = latent_loss(pred - latents) + config.contact_weight * depth_mm
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        depth_sum += float(depth_mm.detach())
    decoder.autoencoder.requires_grad_(True)
    after = inside_fraction(model, decoder, val) if val is not None else float("nan")
    summary = {
        "steps": config.contact_steps,
        "weight": config.contact_weight,
        "margin_m": config.contact_margin_m,
        "against": train.contacts.against,
        "mean_depth_mm": depth_sum / max(config.contact_steps, 1),
        "val_inside_before": before,
        "val_inside_after": after,
        "minutes": (time.perf_counter() - started) / 60,
    }
    save_phase(path, key, model, summary=summary)
    return summary


def model_contact_windows(
    folder: Path, ds: GarmentDataset, split: str, against: str = "visible"
) -> ContactWindows:
    """A trained model's windows of ``split`` of its dataset, standardised as it was trained, with
    their frames' bodies (``against``: as :meth:`BodyContacts.of`): what the phase takes, for a tool
    or a test that runs it on a finished model (``folder`` holds its bundle and its autoencoder
    stage's latents)."""
    from ..artifacts.bundle_loader import load_bundle
    from ..data.windows import build_windows, dataset_features

    bundle = load_bundle(folder)
    config = bundle.codespace.config
    names = ds.splits[split]
    with np.load(Path(folder) / "autoencoder" / "latents.npz", allow_pickle=False) as f:
        latents = {n: f[n] for n in names}
    windows = build_windows(
        dataset_features(ds, names, config),
        latents,
        names,
        window=config.window,
    )
    return ContactWindows(
        WindowTensors.of(windows, bundle.motion_stats, bundle.latent_stats),
        BodyContacts.of(ds, windows, against),
    )
