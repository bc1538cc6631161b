"""The sampler's contact phase: its draws taught to keep out of the body.

Flow matching learns the departures from simulations that keep the cloth out of the body, but it
never sees the body: where the cloth lies on it, a draw's error puts it inside. On the character
model of docs/sampler.md, 4.8 % of a draw's vertices lay inside the visible body before the
push-out (the regression 1.3 %), and the push-out's work in a crowd doubled. This is the code
space's contact phase (:mod:`.contact`) for the draw.

After the flow's training, ``contact_steps`` Adam steps on the sampler, each on a batch of training
frames: the flow's loss as in training, plus ``contact_weight`` times the mean depth (mm) by which
the frames' draws fall inside the body grown by ``contact_margin_m``, plus the draws' squared
distance to the trained flow's draws from the same noise (``contact_anchor`` times their mean
square, in the departures' scaled units). That anchor is
what keeps the draw a draw: a draw of one Euler step reads the velocity at the flow's start only,
which the flow's loss, spread over the flow's times, barely holds; without it the phase took the
validation clips' energy score from 27.4 to 39.0 mm (the cloth moved off the body wholesale). A
draw is made as run time
makes it (the model's Euler steps from the noise, differentiable), at a temperature drawn from the
calibration's range (:data:`~.sampler_calibration.TEMPERATURES`: the phase comes before the
calibration), decoded by the frozen mesh decoder on the body each frame was simulated on (its skin
where it has one, :class:`~.contact.BodyContacts`).
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from pathlib import Path

import torch
from tqdm.auto import tqdm

from ..models.sampler import ClothSampler
from .contact import BodyContacts, FrameDecoder, evenly_spaced, load_phase, save_phase, share_inside
from .sampler_calibration import TEMPERATURES

LEARNING_RATE = 1e-4  # a third of training's rate: the phase adjusts a trained flow
BATCH = 64  # frames (and so decoded draws) a step
REPORT_FRAMES = 512  # validation frames the report draws before and after
REPORT_TEMPERATURE = 0.7  # the temperature of the report's draws

# (sampler, frames, rows, generator) -> the rows' condition context and scaled target (.sampler's batch)
Condition = Callable[[ClothSampler, object, torch.Tensor, torch.Generator], tuple[torch.Tensor, torch.Tensor]]


def drawn_rows(model: ClothSampler, frames, context: torch.Tensor, noise: torch.Tensor, rows) -> torch.Tensor:
    """The standardised latents (n, L) of frames ``rows`` drawn from ``noise`` (scaled already by a
    temperature) in the model's Euler steps: differentiable, as the phase needs."""
    scaled = model.draw(context, noise, model.config.steps)
    return frames.mean[rows] + scaled * model.residual_scale


@torch.no_grad()
def draw_inside_fraction(
    model: ClothSampler, frames, bodies: tuple[FrameDecoder, BodyContacts], condition: Condition, shape
) -> float:
    """The fraction of vertices more than 5 mm inside the body in seeded draws (temperature
    :data:`REPORT_TEMPERATURE`) of up to :data:`REPORT_FRAMES` of ``frames``, evenly spaced."""
    decoder, contacts = bodies
    if not len(frames.mean):
        return float("nan")
    gen = torch.Generator().manual_seed(7919)

    def distances(rows: torch.Tensor) -> torch.Tensor:
        context, target = condition(model, frames, rows, gen)
        noise = REPORT_TEMPERATURE * torch.randn(target.shape, generator=gen)
        latents = drawn_rows(model, frames, context, noise, rows)
        return decoder.distance(latents.reshape(len(rows), *shape), contacts, rows)

    return share_inside(
        distances(rows) for rows in evenly_spaced(len(frames.mean), REPORT_FRAMES).split(BATCH)
    )


def teach_sampler_contact(
    model: ClothSampler,
    data: tuple,
    bodies: tuple[FrameDecoder, BodyContacts, BodyContacts],
    *,
    condition: Condition,
    config,
    shape: tuple[int, ...],
    checkpoint: tuple[Path, str],
    progress: bool = True,
) -> dict:
    """Run the phase (module docstring; ``config``: the stage's training settings, its
    ``contact_steps``, ``contact_weight``, ``contact_margin_m``, ``contact_anchor`` and ``seed``) on
    ``model`` in place, on ``data`` (train, val frames) with ``bodies`` (the frame decoder, the train
    and val frames' bodies) and return its summary, with the share of the validation draws' vertices
    inside the body before and after. ``shape``: the latents' (nodes, C). Kept at ``checkpoint``
    (path, key): a re-run with the same key loads it instead."""
    path, key = checkpoint
    if (kept := load_phase(path, key, model)) is not None:
        return kept
    (train, val), (decoder, train_bodies, val_bodies) = data, bodies
    decoder.autoencoder.requires_grad_(False)  # frozen: its gradients would be computed for nothing
    model.eval()
    before = draw_inside_fraction(model, val, (decoder, val_bodies), condition, shape)
    trained = copy.deepcopy(model).requires_grad_(False)  # the flow as trained: the draws' anchor
    optimizer = torch.optim.Adam(model.parameters(), lr=LEARNING_RATE)
    gen = torch.Generator().manual_seed(config.seed + 104729)
    low, high = min(TEMPERATURES), max(TEMPERATURES)
    started, sums = time.perf_counter(), {"depth": 0.0, "flow": 0.0, "anchor": 0.0}
    for _ in tqdm(range(config.contact_steps), desc="sampler contact", unit="step", disable=not progress):
        rows = torch.randint(0, len(train.mean), (min(BATCH, len(train.mean)),), generator=gen)
        state = gen.get_state()  # the anchor's condition drawn as the model's (a history's noise alike)
        context, target = condition(model, train, rows, gen)
        flow = model.flow_loss(
            context, target, torch.randn(target.shape, generator=gen), torch.rand(len(rows), generator=gen)
        )
        temperature = low + (high - low) * torch.rand(len(rows), 1, generator=gen)
        noise = temperature * torch.randn(target.shape, generator=gen)
        latents = drawn_rows(model, train, context, noise, rows)
        with torch.no_grad():
            anchored = condition(trained, train, rows, torch.Generator().set_state(state))[0]
            anchor = drawn_rows(trained, train, anchored, noise, rows)
        gap = ((latents - anchor) / model.residual_scale).square().mean()
        distance = decoder.distance(
            latents.reshape(len(rows), *shape), train_bodies, rows, reach_m=config.contact_margin_m
        )
        depth_mm = 1000.0 * torch.relu(config.contact_margin_m - distance).mean()
        loss = flow + config.contact_anchor * gap + config.contact_weight * depth_mm
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        for name, value in (("depth", depth_mm), ("flow", flow), ("anchor", gap)):
            sums[name] += float(value.detach())
    decoder.autoencoder.requires_grad_(True)
    model.eval()
    steps = max(config.contact_steps, 1)
    summary = {
        "steps": config.contact_steps,
        "weight": config.contact_weight,
        "margin_m": config.contact_margin_m,
        "against": train_bodies.against,
        "anchor": config.contact_anchor,
        "mean_depth_mm": sums["depth"] / steps,
        "mean_flow_loss": sums["flow"] / steps,
        "mean_anchor_gap": sums["anchor"] / steps,
        "val_inside_before": before,
        "val_inside_after": draw_inside_fraction(model, val, (decoder, val_bodies), condition, shape),
        "minutes": (time.perf_counter() - started) / 60,
    }
    save_phase(path, key, model, summary=summary)
    return summary
