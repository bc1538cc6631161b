"""The sampler's draw calibrated on the validation clips, after its training
(:mod:`.sampler`): how wide a draw is (the noise's ``temperature``) and how fast it moves (the
noise's pole, ``noise_decay``; :class:`~hrr_garment.models.sampler.SampleTrack`).

- **Temperature** first, at a middle pole: the candidate of :data:`TEMPERATURES` whose seeded draw
  of the validation clips is as sharp as their simulation (its mean bending energy nearest the
  truth's: :mod:`hrr_garment.garment.cloth_energy`). Each candidate's energy score of two draws
  against the clips' simulation, E|X - y| - 1/2 E|X - X'| (PVE as the distance), is recorded
  beside it: that score, proper with one observation, kept rising with the temperature up to 1
  on the character model of docs/sampler.md, whose draws at 1 were 1.44 x as sharp as the
  simulation on these clips and 1.42 x on its test clips: the regression's own error on unseen
  clips reads to the score as spread to cover.
- **Pole** then: the fastest of :data:`NOISE_DECAYS` whose draw moves about no more than the
  simulation (mean acceleration at most the truth's): a faster noise is a livelier cloth, and past
  that, jitter; the slowest where none does.
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from ..garment.cloth_energy import MeshTopology, cloth_energies
from ..models.sampler import ClothSampler
from .bundle_stage import decoded_frames, frames_pve_mm

TEMPERATURES = (0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)  # the noise's scales tried
NOISE_DECAYS = (0.5, 0.7, 0.8, 0.9, 0.95, 0.98)  # the noise's poles tried, fastest first
TEMPERATURE_POLE = 0.8  # the pole the temperatures are compared at


def mean_acceleration_mm(frames: np.ndarray, lengths: list[int]) -> float:
    """The mean length of the vertices' second differences (mm per frame squared) over sequences of
    ``lengths`` frames laid end to end in ``frames`` (n, V, 3): how much the cloth moves about."""
    parts, start = [], 0
    for n in lengths:
        if n >= 3:
            parts.append(np.linalg.norm(np.diff(frames[start : start + n], 2, axis=0), axis=-1).ravel())
        start += n
    return 1000.0 * float(np.concatenate(parts).mean()) if parts else 0.0


def drawn_latents(model: ClothSampler, frames, seed: int) -> list[np.ndarray]:
    """Each sequence of ``frames`` (:class:`~.sampler.SamplerFrames`) drawn whole from ``seed``
    (standardised latents (T, L) each)."""
    pairs = zip(frames.sequences(frames.features), frames.sequences(frames.mean))
    return [model.roll_out(feats, mean, seed=seed).numpy() for feats, mean in pairs]


def calibrate_draws(model: ClothSampler, bundle, val: tuple, *, seed: int, progress: bool = True) -> dict:
    """Set the sampler's ``temperature`` and ``noise_decay`` on ``val`` (its
    :class:`~.sampler.SamplerFrames` and their simulated frames) as the module docstring says;
    -> both, with each candidate's sharpness (bending energy over the truth's), energy score (mm)
    and acceleration over the truth's, and the chosen draw's distance to the clips' simulation
    (``validation_mm``)."""
    frames, truth = val

    def draw(draw_seed: int) -> np.ndarray:
        return decoded_frames(bundle, drawn_latents(model, frames, draw_seed))

    topology = MeshTopology.of(bundle.template.faces, bundle.template.num_vertices)
    rest = bundle.template.vertices.astype(np.float64)

    def bending(vertices: np.ndarray) -> float:
        return float(cloth_energies(vertices.astype(np.float64), rest, topology)[1].mean())

    truth_bending = max(bending(truth), 1e-30)
    scores, sharpness = {}, {}
    model.noise_decay.fill_(TEMPERATURE_POLE)
    for temperature in tqdm(TEMPERATURES, desc="sampler: temperature", disable=not progress, leave=False):
        model.temperature.fill_(temperature)
        a, b = draw(seed), draw(seed + 1)
        to_truth = 0.5 * (frames_pve_mm(a, truth) + frames_pve_mm(b, truth))
        scores[temperature] = to_truth - 0.5 * frames_pve_mm(a, b)
        sharpness[temperature] = bending(a) / truth_bending
    temperature = min(sharpness, key=lambda t: abs(np.log(sharpness[t])))
    model.temperature.fill_(temperature)
    target = mean_acceleration_mm(truth, frames.lengths)
    ratios, distances = {}, {}
    for decay in tqdm(NOISE_DECAYS, desc="sampler: the noise's pole", disable=not progress, leave=False):
        model.noise_decay.fill_(decay)
        drawn = draw(seed)
        ratios[decay] = mean_acceleration_mm(drawn, frames.lengths) / max(target, 1e-9)
        distances[decay] = frames_pve_mm(drawn, truth)
    decay = next((d for d in NOISE_DECAYS if ratios[d] <= 1.0), NOISE_DECAYS[-1])
    model.noise_decay.fill_(decay)
    return {
        "temperature": temperature,  # the candidates as chosen (the buffers hold them in float32)
        "sharpness": {f"{t:g}": v for t, v in sharpness.items()},
        "energy_scores_mm": {f"{t:g}": v for t, v in scores.items()},
        "noise_decay": decay,
        "acceleration_ratios": {f"{d:g}": r for d, r in ratios.items()},
        "validation_mm": distances[decay],  # a seeded draw against the clips' one simulation
    }
