"""The streaming step of a trained model as one PyTorch module: a frame of poses in, the garment's
world vertices out, each character's window state as explicit inputs and outputs. ONNX holds it
(:mod:`hrr_garment.export.onnx_model` exports it) and a GPU runs it (:mod:`.torch_crowd`). The regression path
of :class:`~hrr_garment.inference.stream.CrowdStream`, the frame path's stages (:mod:`.frame_path`,
numbered alike in :meth:`StreamStep.forward`) with the same formulas and the same resolved run:

- before the stages, the poses: local quaternions -> matrices, forward kinematics on the body's
  skeleton (its bone lengths, its pelvis height), as
  :meth:`~hrr_garment.inference.character_body.CharacterBody.play`;
- 1 features: the frame against the character's last one
  (:func:`~hrr_garment.motion.features.pair_features_batch`), its motion memory one frame on
  (:class:`~hrr_garment.motion.memory.MotionMemory`), the body's measures;
- 2 windows: the last W frames;
- 3 choice: the window step (:class:`~hrr_garment.models.codes.WindowCodes`): motion encoder, code
  entropy and classes, the code-space decoder's latents of the window's last frame;
- 4 blending, 5 swing: the regression is one source and its swing runs as predicted (swing 1),
  then the settling lag where the run asks for it (:mod:`.torch_settle`, its state ``settled``
  after the window's); in the sample mode the generative decoder's draw departs from them
  (:mod:`.torch_sample`: the engine's white noise in, each character's draw state carried);
- 6 decoding: the mesh decoder; 7 folds: none (the regression);
- 8 world: the garment's rest offset on the body, the body frame to the world
  (:func:`~hrr_garment.motion.frame.from_body_frame`);
- 9 push_out: against the body's capsules, and its strain limit (:mod:`.torch_push_out`).

A character's first frame is told by ``started`` = 0: its last pose is taken to be this one (zero
velocities), its memory starts at rest and its window is this frame repeated, as a stream starts.
In float32 throughout (the Python stream's FK and memory run in float64): within a few hundredths
of a millimetre of it over a real clip (tests/export/test_onnx.py).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from ..models.codes import WindowCodes
from ..motion.memory import MEMORY_WIDTH, MotionMemory, motion_memory
from ..motion.motion import FPS
from ..motion.rotations import yaw_of
from ..motion.skeleton import NUM_JOINTS, REST_PELVIS_HEIGHT
from .collision import PUSH_OUT
from .frame_path import FramePath
from .modes import Mode
from .torch_features import FeatureStage, PoseStage
from .torch_ops import constant, turn_y
from .torch_push_out import PushOutStage
from .torch_sample import SampleStage
from .torch_settle import SettleStage


class StreamStep(nn.Module):
    """One frame of N characters through the regression path, or the sample mode's (``sample``); see
    the module docstring.

    Inputs: ``rotations`` (N, 22, 4) local quaternions x y z w, ``root`` (N, 3) pelvis positions
    (metres, Y up), and the state: ``started`` (N,) 0 at a character's first frame else 1,
    ``previous_rotations`` (N, 22, 3, 3), ``previous_positions`` (N, 22, 3), ``memory`` (N, rows, 64),
    ``window`` (N, W - 1, F); with ``settle``, then ``settled`` (N, nodes C + 1); with ``sample``,
    then ``noise`` (N, 2, L) white noise and the draw's
    state ``sample_drive``, ``sample_noise``, ``sample_latents`` (N, L). Outputs: ``vertices`` (N, V,
    3), ``entropy`` (N,), ``codes`` (N, G), and the next state in the same order (``started`` all
    ones)."""

    def __init__(  # noqa: PLR0913  (the step's stages, each its own)
        self,
        bundle,
        decoder,
        *,
        character,
        memory: MotionMemory | None,
        fps: float,
        push_out: PushOutStage | None,
        sample: SampleStage | None = None,
        cloth: np.ndarray | None = None,
        settle: SettleStage | None = None,
    ):
        super().__init__()
        record = character.record
        self.pose = PoseStage(record.skeleton.offsets, record.skeleton.parents, record.pelvis_height)
        # the body's measures and the cloth's values where the model reads them (frame_path's stage 1)
        config = bundle.codespace.config
        self.features = FeatureStage(
            memory,
            fps,
            measures=character.vector if config.body_features else None,
            cloth=cloth if config.material_features else None,
        )
        self.codes = WindowCodes(bundle.codespace.eval(), regression=True, last_frame=True)
        constant(self, "motion_mean", bundle.motion_stats.mean)
        constant(self, "motion_std", bundle.motion_stats.std)
        constant(self, "latent_mean", bundle.latent_stats.mean)
        constant(self, "latent_std", bundle.latent_stats.std)
        constant(self, "garment_offset", character.offset)
        constant(self, "rest_pelvis", [0.0, REST_PELVIS_HEIGHT, 0.0])
        self.decoder, self.push_out, self.sample, self.settle = decoder, push_out, sample, settle
        self.latent_shape = tuple(bundle.codespace.latent_shape)
        self.observe = None  # a stage's name and output -> None (tests), as FramePath.observe

    def seen(self, stage: str, value: torch.Tensor) -> torch.Tensor:
        """``value``, the output of ``stage`` (:data:`~.frame_path.STAGES`), shown to
        :attr:`observe` where one is set (a test's; never in an exported graph)."""
        if self.observe is not None:
            self.observe(stage, value.detach().cpu().numpy())
        return value

    def forward(  # noqa: PLR0913  (one argument per graph input: ONNX names each)
        self,
        rotations,
        root,
        started,
        previous_rotations,
        previous_positions,
        memory,
        window,
        settled=None,
        noise=None,
        sample_drive=None,
        sample_noise=None,
        sample_latents=None,
        material=None,
    ):
        """One frame through the frame path's stages (:mod:`.frame_path`), in torch; ``settled``
        the settling lag's state where the step has the lag (None without); the sample mode's white
        ``noise`` and draw state last (None in the regression); ``material`` (N, m) each character's
        cloth values for a model across cloths (:func:`~.run_material.material_columns`; None: the
        run's cloth, which the step holds)."""
        rot, pos = self.pose(rotations, root)
        first = started.reshape(-1, 1, 1) <= 0
        previous = (
            torch.where(first[..., None], rot, previous_rotations),
            torch.where(first, pos, previous_positions),
        )
        # 1. features
        features, memory = self.features(previous, (rot, pos), memory, started, material)
        self.seen("features", features)
        # 2. windows
        past = torch.where(first, features[:, None].expand_as(window), window)
        frames = self.seen("windows", torch.cat([past, features[:, None]], 1))  # (N, W, F)
        # 3. choice: the window step's regression
        standard = (frames - self.motion_mean) / self.motion_std
        entropy, codes, latents = self.codes(standard)
        n = latents.shape[0]
        self.seen("choice", self.destandardised(latents))
        # 4. blending: one source, or the sample mode's draw departing from it
        drawn = ()
        if self.sample is not None:
            drawing = (noise, sample_drive, sample_noise, sample_latents)
            latents, drawn = self.sample(standard[:, -1], latents.reshape(n, -1), first[:, 0], *drawing)
        latents = self.seen("blending", self.destandardised(latents))
        # 5. swing: runs as predicted; then the settling lag where the run asks for it
        lagged = ()
        if self.settle is not None:
            latents, settled = self.settle(latents, features, settled, first)
            lagged = (settled,)
        self.seen("swing", latents)
        # 6. decoding, and 7. folds: none in the regression
        local = self.seen("folds", self.seen("decoding", self.decoder(latents)))
        # 8. world: stood on the body, the body frame to the world
        yaw = yaw_of(rot[:, 0])
        heading = (torch.cos(yaw), torch.sin(yaw))
        origin = root * self.pose.root_scale - self.rest_pelvis
        world = self.seen("world", turn_y(local + self.garment_offset, *heading) + origin[:, None])
        # 9. push-out
        if self.push_out is not None:
            world = self.push_out(world, rot, pos, heading)
        self.seen("push_out", world)
        state = (torch.ones_like(started), rot, pos, memory, frames[:, 1:], *lagged, *drawn)
        return (world, entropy, codes, *state)

    def destandardised(self, latents: torch.Tensor) -> torch.Tensor:
        """The code-space decoder's standardised latents (N, ...) as the mesh decoder's (N, nodes, C)."""
        n = latents.shape[0]
        return (latents.reshape(n, -1) * self.latent_std + self.latent_mean).reshape(n, *self.latent_shape)


class TorchDecoder(nn.Module):
    """The mesh decoder's PyTorch blocks (gathers and batched matmuls, the folded kernels of a
    :class:`~hrr_garment.models.inference_decoder.InferenceDecoder`) as a module to export: the
    inference decoder itself calls the native kernels, which a graph cannot hold."""

    def __init__(self, inference_decoder):
        super().__init__()
        self.inference_decoder = inference_decoder

    def forward(self, latents: torch.Tensor) -> torch.Tensor:
        return self.inference_decoder._torch_forward(latents)


class AutoencoderDecoder(nn.Module):
    """The mesh autoencoder's own decoder as a module that moves to a device with its weights (a
    :class:`~hrr_garment.models.inference_decoder.InferenceDecoder` keeps its folded kernels beside the
    module, on the CPU): what a step on a GPU decodes with where it runs the full decoder."""

    def __init__(self, autoencoder):
        super().__init__()
        self.autoencoder = autoencoder

    def forward(self, latents: torch.Tensor) -> torch.Tensor:
        return self.autoencoder.decode(latents)


def stream_step(path: FramePath, *, movable: bool = False) -> StreamStep:
    """The :class:`StreamStep` of a frame path (:class:`~.frame_path.FramePath`: a model under a
    resolved run: its body, ``push_out``, ``push_body``, ``decoder`` and ``push``), at the rate
    every model streams at (:data:`~hrr_garment.motion.motion.FPS`). The full decoder is the mesh
    decoder's folded blocks, or with ``movable`` the autoencoder's own, which moves to a GPU; the
    fast one the bundle's subspace decoder. The sample mode draws ``sample_steps`` steps a frame."""
    bundle, run = path.bundle, path.run
    if run.mode not in (Mode.REGRESSION, Mode.SAMPLE):
        raise ValueError(
            f"the torch step runs the regression or the sample mode (mode='regression' or 'sample'), "
            f"not {run.mode.value!r}"
        )
    if run.swing != 1.0:
        raise ValueError(f"the torch step runs the swing as predicted (swing 1), not swing={run.swing:g}")
    spec = bundle.codespace.config.memory
    memory = motion_memory(spec, FPS) if spec else None
    stage = None
    if run.push_out:
        # the mesh the run's body is drawn with, where the run pushes out of it (push_body "visible",
        # the default) and the body has one; else its capsules
        visible = run.body.visible_collider() if run.push_body == "visible" else None
        body, settings = run.body.body, path.push_settings or PUSH_OUT
        stage = (
            PushOutStage((*body.ends, body.radii), path.smoothing, limits=path.push_limits, settings=settings)
            if visible is None
            else PushOutStage.of_visible(visible, path.smoothing, limits=path.push_limits, settings=settings)
        )
    if run.decoder == "fast":
        module = path.decoder
    else:
        module = AutoencoderDecoder(bundle.autoencoder) if movable else TorchDecoder(path.decoder)
    sample = SampleStage(bundle.sampler, run.sample_steps) if run.mode is Mode.SAMPLE else None
    return StreamStep(
        bundle,
        module,
        character=run.body,
        memory=memory,
        fps=FPS,
        push_out=stage,
        sample=sample,
        cloth=path.cloth,
        settle=SettleStage(run.settle, FPS) if run.settle > 0 else None,
    ).eval()


def state_shapes(step: StreamStep) -> dict[str, tuple[int, ...]]:
    """Each state input's shape per character, in the step's order (the sample mode's draw state
    after the white noise it takes, :func:`noise_shape`)."""
    window = step.codes.codespace.config.window
    shapes = dict(
        zip(
            STATE,
            [
                (),
                (NUM_JOINTS, 3, 3),
                (NUM_JOINTS, 3),
                (max(step.features.rows, 1), MEMORY_WIDTH),
                (window - 1, int(step.motion_mean.shape[0])),
            ],
        )
    )
    if step.settle is not None:  # the lagged latents, flattened, and the stillness clock's reading
        shapes[SETTLE_STATE] = (int(np.prod(step.latent_shape)) + 1,)
    if step.sample is not None:
        shapes |= {name: (step.sample.size,) for name in SAMPLE_STATE}
    return shapes


# each character's state, as the step takes it and gives it back
STATE = ("started", "previous_rotations", "previous_positions", "memory", "window")
# the settling lag's state (inference/torch_settle.py), where the run asks for the lag
SETTLE_STATE = "settled"
# the sample mode's draw state: the noise's two filters and the regression's latents of the frame before
SAMPLE_STATE = ("sample_drive", "sample_noise", "sample_latents")


def noise_shape(step: StreamStep) -> tuple[int, ...] | None:
    """The shape per character of the white noise a sample mode's step takes (None: it takes none)."""
    return None if step.sample is None else (2, step.sample.size)
