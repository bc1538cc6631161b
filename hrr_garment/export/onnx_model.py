"""A trained model's streaming step as ONNX, for engines that cannot call Python (Unreal's neural
engine, Unity's inference engine, onnxruntime): ``hrr-export-model MODEL --onnx -o dress.onnx``.

    step = export_onnx(animator, "dress.onnx")                  # + dress.tensors.npz
    gap = check_onnx(animator, "dress.onnx", motion)            # against the Python stream, mm

The graph (:class:`~hrr_garment.inference.torch_step.StreamStep`) is the regression path of a stream for N
characters of one body, or the sample mode's (``mode="sample"``): a frame of poses in, world vertices out,
each character's window state as explicit inputs and outputs (:data:`STATE`, and the sample mode's draw
state after its white noise input; :func:`initial_state` gives a first frame's). What ONNX cannot
hold, the retrieval database (a FAISS search over binary codes), travels as documented tensors in
the companion npz (:data:`TENSORS`) beside the garment's faces, with the codes and entropies the
graph outputs for a search of one's own (docs/export.md). Needs the ``onnx`` extra.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from ..errors import InputError
from ..garment.material_range import MaterialRange, material_vector
from ..inference.frame_path import FramePath
from ..inference.modes import Mode
from ..inference.run_settings import DECODERS, PUSHES, RunSettings
from ..inference.torch_step import SETTLE_STATE, STATE, noise_shape, state_shapes, stream_step
from ..io_utils import atomic_path, refuse_inputs_as_outputs, require_suffix
from ..models.sampler import characters_noise
from ..motion.motion import Motion
from ..motion.poses import motion_to_poses
from ..motion.skeleton import NUM_JOINTS
from .graph_export import export_graph
from .onnx_record import TENSORS, graph_metadata, record_metadata, tensors_path, write_tensors
from .stage_progress import stage_progress

INPUTS = ("rotations", "root")
# a model across cloths' graph: each character's cloth values (N, 5) after the poses
# (hrr_garment.garment.material_range: log10 density, stretch, shear, bend; damping)
MATERIAL = "material"
OUTPUTS = ("vertices", "entropy", "codes") + tuple(f"next_{name}" for name in STATE)
# the sample mode's graph: its white noise input after the state, and its draw state after the
# window's (and the settling lag's, where the graph has the lag)
NOISE = "noise"
OPSET = 18
# what an export's progress bar names: torch's trace of the step (most of the time), its optimiser, the files
EXPORT_STAGES = ("tracing the step", "optimising the graph", "writing")


@dataclass(frozen=True)
class OnnxExport:
    """What :func:`export_onnx` wrote."""

    graph: Path
    tensors: Path
    vertices: int
    state: dict  # input name -> shape per character (without the leading N)
    seconds: float
    noise: tuple[int, ...] | None = None  # the sample mode's white noise per character (None: none)


def _require_onnx():
    try:
        import onnx
        import onnxscript  # noqa: F401  (torch's ONNX exporter translates through it)
    except ImportError:
        raise ImportError("ONNX export needs onnx and onnxscript: pip install 'hrr_garment[onnx]'") from None
    return onnx


def _onnxruntime():
    try:
        import onnxruntime
    except ImportError:
        raise ImportError(
            "running an ONNX model needs onnxruntime: pip install 'hrr_garment[onnx]'"
        ) from None
    return onnxruntime


def initial_state(shapes: dict[str, tuple[int, ...]], characters: int) -> dict[str, np.ndarray]:
    """Zeros of each state input for ``characters`` starting characters (``started`` 0: every
    other state input is then read as nothing before)."""
    return {name: np.zeros((characters, *shape), np.float32) for name, shape in shapes.items()}


def export_onnx(
    animator, path: str | Path, settings: RunSettings | None = None, *, progress: bool = False, **changes
) -> OnnxExport:
    """Write ``path`` (.onnx, one file) and its companion ``<stem>.tensors.npz``, atomically, for the
    run ``settings`` ask (:class:`~hrr_garment.inference.run_settings.RunSettings`, with keyword
    ``changes``, as :meth:`~hrr_garment.inference.animator.Animator.animate` takes them; the mode is
    the regression, or ``mode="sample"``: the generative decoder's draw, ``sample_steps`` a frame, the
    engine's white noise in): its ``body`` (None: the model's own), ``push_out``, ``decoder``
    ("full": the mesh decoder's folded kernels, or "fast": the subspace decoder, a graph a fraction
    of the size and a step a fraction of the time) and ``push`` ("mesh", or "subspace": the push
    along the fast decoder's components first, fewer tears). ``progress``: a bar of the export's
    stages, its clock running through torch's trace (a minute to a few on a CPU)."""
    onnx = _require_onnx()
    path = Path(path)
    require_suffix(path, (".onnx",), "an ONNX model")
    tensors = tensors_path(path)
    refuse_inputs_as_outputs(path, tensors)  # neither written where the other would then fail
    t0 = time.perf_counter()
    # refuses a fast decoder or a subspace push without the bundle's fast decoder, before the export's minute
    asked = changes.get("mode", None if settings is None else settings.mode)
    mode = Mode.SAMPLE if asked == Mode.SAMPLE else Mode.REGRESSION  # a str enum: the name too
    run = animator.resolve(settings, **{**changes, "mode": mode, "causal": True})
    with stage_progress(EXPORT_STAGES, desc=f"ONNX export of {path.name}", enabled=progress) as stage:
        stage(EXPORT_STAGES[0])
        frame_path = FramePath(animator, run)
        step = stream_step(frame_path)
        shapes, noise = state_shapes(step), noise_shape(step)
        example = _example_inputs(shapes, noise, 2, frame_path.cloth)
        n = torch.export.Dim("characters", min=1, max=4096)
        dynamic = (tuple({0: n} for _ in example),)  # the inputs, one tuple (GraphInputs' *inputs)
        program = export_graph(
            GraphInputs(step, list(example)),
            tuple(torch.from_numpy(x) for x in example.values()),
            input_names=list(example),
            output_names=list(OUTPUTS) + [f"next_{name}" for name in shapes if name not in STATE],
            dynamic_shapes=dynamic,
            opset=OPSET,
            strict_first=True,  # its push-out's loops (graph_export)
            traced=lambda: stage(EXPORT_STAGES[1]),
        )
        stage(EXPORT_STAGES[2])
        model = program.model_proto
        record_metadata(
            model, graph_metadata(animator.bundle, run, shapes=shapes, noise=noise, cloth=frame_path.cloth)
        )
        with atomic_path(path) as tmp:
            onnx.save_model(model, str(tmp))
        write_tensors(tensors, animator.bundle)
    vertices = int(animator.bundle.template.num_vertices)
    return OnnxExport(path, tensors, vertices, shapes, time.perf_counter() - t0, noise)


class GraphInputs(torch.nn.Module):
    """The step with the graph's inputs in the graph's order, each handed to it by name: the poses,
    a model across cloths' :data:`MATERIAL`, the state, the sample mode's noise and draw state, as
    the graph has them (:func:`_example_inputs`)."""

    def __init__(self, step: torch.nn.Module, names: list[str]):
        super().__init__()
        self.step, self.names = step, list(names)

    def forward(self, *inputs):
        return self.step(**dict(zip(self.names, inputs)))


def _example_inputs(
    shapes: dict, noise: tuple | None, characters: int, cloth: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """The step's inputs in its order: poses, the cloth's values (a model across cloths), the window
    state, the sample mode's noise and draw state."""
    rng = np.random.default_rng(0)
    quats = rng.normal(size=(characters, NUM_JOINTS, 4)).astype(np.float32)
    inputs = {
        "rotations": quats / np.linalg.norm(quats, axis=-1, keepdims=True),
        "root": np.tile(np.float32([0.0, 0.96, 0.0]), (characters, 1)),
    }
    if cloth is not None:
        inputs[MATERIAL] = np.tile(np.asarray(cloth, np.float32), (characters, 1))
    state = initial_state(shapes, characters)
    inputs |= {name: state.pop(name) for name in STATE}
    if SETTLE_STATE in state:  # the settling lag's, after the window's
        inputs[SETTLE_STATE] = state.pop(SETTLE_STATE)
    if noise is not None:
        inputs[NOISE] = rng.standard_normal((characters, *noise)).astype(np.float32)
    return inputs | state


class OnnxStream:
    """A graph written by :func:`export_onnx` run by onnxruntime, its state kept: one frame of N
    characters per :meth:`push` (what examples/onnx_stream.py does without the package). A sample
    mode's graph is fed each character's white noise from a generator seeded with ``seeds`` (one
    seed for every character, as a crowd's run seed, or one each): what the Python stream draws
    from the same seed."""

    def __init__(
        self,
        path: str | Path,
        threads: int | None = None,
        seeds: int | Sequence[int] = 0,
        material: object = None,
    ):
        ort = _onnxruntime()
        options = ort.SessionOptions()
        if threads:
            options.intra_op_num_threads = threads
        try:
            self.session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception types for a file it cannot read
            raise InputError(path, f"not an ONNX model onnxruntime can load ({exc})") from None
        meta = self.session.get_modelmeta().custom_metadata_map
        if "state" not in meta:
            raise InputError(
                path, "not a streaming step written by hrr-export-model --onnx (no state in its metadata)"
            )
        self.shapes = {k: tuple(v) for k, v in json.loads(meta["state"]).items()}
        # the run the graph holds, as Animator.stream and crowd take it (graphs written before the
        # decoder, push and push body were recorded: the full decoder, the mesh push and the capsules,
        # which every graph pushed out of before issue 82)
        self.settings = {
            "mode": meta.get("path", "regression"),
            "push_out": json.loads(meta["push_out"]),
            "decoder": meta.get("decoder", DECODERS[0]),
            "push": meta.get("push", PUSHES[0]),
            "push_body": meta.get("push_body", "capsules"),
            "settle": float(json.loads(meta.get("settle", "0"))),  # the settling lag (0: none)
        }
        self.noise = tuple(json.loads(meta["noise"])) if "noise" in meta else None
        self.path, self._meta = Path(path), meta
        self.material = None  # a model across cloths' graph: every character's cloth values (m,)
        if MATERIAL in meta:
            self.dress(material)
        elif material is not None:
            raise InputError(path, "its model was trained in one cloth: the graph takes no material")
        if self.noise is not None:
            self.settings["sample_steps"] = json.loads(meta["sample_steps"])
        self.outputs = list(OUTPUTS) + [f"next_{name}" for name in self.shapes if name not in STATE]
        self.seeds, self.generators = seeds, None
        self.state: dict[str, np.ndarray] | None = None

    def dress(self, material: object = None) -> None:
        """Every character's cloth, for a graph of a model across cloths: ``material`` (what
        ``RunSettings.material`` takes) checked against the range the graph records, or the cloth
        it was exported with where None; ``settings["material"]`` is then that cloth."""
        from ..garment.material import material_from

        meta = self._meta
        where = str(self.path)
        cloth = material_from(json.loads(meta["material_default"]) if material is None else material, where)
        outside = MaterialRange.from_dict(json.loads(meta["material_range"])).outside(material_vector(cloth))
        if outside:
            raise InputError(
                where, f"cloth {cloth.name!r} is outside its model's range: {'; '.join(outside)}"
            )
        self.material, self.settings["material"] = material_vector(cloth), cloth

    def push(self, rotations: np.ndarray, roots: np.ndarray) -> np.ndarray:
        """(N, 22, 4) quaternions x y z w and (N, 3) roots -> (N, V, 3) world vertices."""
        if self.state is None:
            self.state = initial_state(self.shapes, len(rotations))
        feed = {"rotations": np.asarray(rotations, np.float32), "root": np.asarray(roots, np.float32)}
        if self.material is not None:
            feed[MATERIAL] = np.tile(self.material, (len(rotations), 1))
        if self.noise is not None:
            feed[NOISE] = self._white_noise(len(rotations))
        out = self.session.run(self.outputs, feed | self.state)
        self.state = dict(zip(self.shapes, out[3:]))
        return out[0]

    def _white_noise(self, characters: int) -> np.ndarray:
        """(N, 2, L): each character's white noise this frame from its seeded generator."""
        if self.generators is None:
            seeds = [self.seeds] * characters if isinstance(self.seeds, int) else list(self.seeds)
            if len(seeds) != characters:
                raise ValueError(f"{len(seeds)} seeds for {characters} characters")
            self.generators = [torch.Generator().manual_seed(int(seed)) for seed in seeds]
        return characters_noise(self.generators, self.noise[1], list(self.state["started"] <= 0)).numpy()


def check_onnx(
    animator, path: str | Path, motion: Motion, settings: RunSettings | None = None, **changes
) -> dict:
    """Stream ``motion`` (canonical skeleton) through the ONNX graph and through
    :meth:`~hrr_garment.inference.animator.Animator.stream`, on the body ``settings`` and ``changes``
    ask (as :func:`export_onnx`; the mode, push-out, decoder and push as the graph was written; a
    sample mode's graph drawn from the ``seed`` of ``changes``, 0 without one, on both) -> the gap
    per frame in millimetres: max, mean, and each path's median step time in milliseconds."""
    seed = changes.get("seed", 0 if settings is None else settings.seed)
    material = changes.get("material", None if settings is None else settings.material)
    runner = OnnxStream(path, seeds=seed)
    if runner.material is not None and material is not None:  # a graph with a material input
        runner.dress(material)
    python = animator.stream(settings, **{**changes, **runner.settings})
    quats, roots = motion_to_poses(motion)
    gaps, onnx_s, python_s = [], [], []
    for t in range(motion.num_frames):
        t0 = time.perf_counter()
        ours = runner.push(quats[t : t + 1], roots[t : t + 1])[0]
        t1 = time.perf_counter()
        theirs = python.push(rotation=quats[t], root=roots[t])
        t2 = time.perf_counter()
        onnx_s.append(t1 - t0)
        python_s.append(t2 - t1)
        gaps.append(np.linalg.norm(ours.astype(np.float64) - theirs, axis=-1).max() * 1000.0)
    gaps = np.array(gaps)
    return {
        "frames": motion.num_frames,
        "max_mm": float(gaps.max()),
        "mean_mm": float(gaps.mean()),
        "onnx_ms": float(np.median(onnx_s) * 1000),
        "python_ms": float(np.median(python_s) * 1000),
    }


__all__ = [
    "INPUTS",
    "NOISE",
    "STATE",
    "OUTPUTS",
    "TENSORS",
    "OnnxExport",
    "OnnxStream",
    "export_onnx",
    "check_onnx",
    "initial_state",
    "state_shapes",
    "stream_step",
]
