"""The fuzzer's Python API cases (tools/fuzz.py): library calls with a hostile value, each with the
words its refusal should use; an output path that is an input; a run interrupted by a signal."""

from __future__ import annotations

import shutil
import signal
import sys
from pathlib import Path

import numpy as np
from fuzz_samples import Case, Samples, _cli, file_digest

# Python API calls with a hostile value V (an expression), each with the words its refusal should use
API_PRELUDE = """
import sys, warnings
import numpy as np
from hrr_garment.inference.animator import Animator
from hrr_garment.motion.io import load_motion
from hrr_garment.motion.motion import Motion
animator, clip, out = Animator.load(sys.argv[1]), load_motion(sys.argv[2]), sys.argv[3]
R, T = clip.local_rotations, clip.root_translation
def save(vertices, root):  # relative to the pelvis: check_output judges the reach
    np.save(out, np.asarray(vertices, np.float64) - np.asarray(root, np.float64).reshape(-1, 1, 3))
try:
{call}
except (ValueError, TypeError, KeyError) as exc:
    print(f"api: error: {{type(exc).__name__}}: {{exc}}", file=sys.stderr)
    sys.exit(2)
"""
API_CALLS = {
    "stream root": (
        "v = animator.stream().push(rotation=R[0], root=V); save(v[None], V)",
        ["root"],
        [
            "[1e39, 0.95, 0]",
            "[1e30, 0.95, 0]",
            "[np.nan, 0.9, 0]",
            "[1, 2]",
            "'abc'",
            "[[0, 0.9, 0]] * 2",
            "np.array([0, 0.9, 0], complex)",
            "[1e4 - 1, 0.9, 0]",
        ],
    ),
    "stream rotation": (
        "v = animator.stream().push(rotation=V, root=T[0]); save(v[None], T[0])",
        ["rotation", "quaternion", "axis-angle", "matrix"],
        [
            "R[0] * 1000",
            "np.full((22, 4), 1e39)",
            "np.zeros((22, 4))",
            "np.full((22, 3), 1e39)",
            "R[0].astype(complex)",
            "np.ones((21, 4))",
            "np.full((22, 3), np.nan)",
            "-R[0]",
            "np.random.default_rng(0).normal(size=(22, 3, 3))",
        ],
    ),
    "teleport": (
        "s = animator.stream()\n    for t in range(5): s.push(rotation=R[t], root=T[t])\n"
        "    root = T[5] + np.array(V, float)\n    v = s.push(rotation=R[5], root=root); save(v[None], root)",
        ["root"],
        ["[50, 0, 0]", "[1e38, 0, 0]", "[0, 3, 0]", "[9000, 0, 0]", "[0.01, 0, 0]"],
    ),
    "motion fps": (
        "m = Motion(R, T, fps=V); a = animator.animate(m); save(a.vertices, a.joints[:, 0])",
        ["frame rate"],
        ["1e-300", "1e300", "0", "-30", "np.nan", "'30'", "True", "None", "complex(30, 1)"],
    ),
    "motion root": (
        "r = T.copy(); r[3] = V; a = animator.animate(Motion(R, r, fps=clip.fps)); "
        "save(a.vertices, a.joints[:, 0])",
        ["pelvis", "non-finite", "root"],
        ["1e39", "1e30", "np.nan", "[1e5, 0, 0]", "-np.inf"],
    ),
    "motion rotation": (
        "q = R.copy(); q[3, 5] = V; a = animator.animate(Motion(q, T, fps=clip.fps)); "
        "save(a.vertices, a.joints[:, 0])",
        ["rotation", "non-finite"],
        ["q[3, 5] * 1000", "0", "np.nan", "-q[3, 5]", "np.diag([1, 1, -1])"],
    ),
    "motion edited": (
        "clip.local_rotations[3, 5] = V\n    a = animator.animate(clip); save(a.vertices, a.joints[:, 0])",
        ["read-only"],
        ["np.nan", "0", "R[3, 5] * 1000"],
    ),
    "tau": (
        "a = animator.animate(clip, tau=V); save(a.vertices, a.joints[:, 0])",
        ["tau"],
        ["np.nan", "-1", "np.inf", "'x'", "None", "1e308", "0.0", "True"],
    ),
    "exclude_sequence": (
        "a = animator.animate(clip, mode='retrieval', exclude_sequence=V); save(a.vertices, a.joints[:, 0])",
        ["exclude_sequence"],
        ["999", "-1", "1.5", "'x'", "True", "0", "np.int64(1)", "2**63"],
    ),
}


def _api_case(number: int, samples: Samples, out: Path, rng: np.random.Generator) -> Case:
    name = str(rng.choice(sorted(API_CALLS)))
    call, words, values = API_CALLS[name]
    value = values[int(rng.integers(len(values)))]
    code = API_PRELUDE.format(call="    " + call.replace("V", f"({value})"))
    return Case(
        number,
        "api",
        f"{name}: {value}",
        [sys.executable, "-c", code, str(samples.model), str(samples.native), str(out / "api.npy")],
        out / "api.npy",
        words,
    )


def _output_is_input_case(number: int, samples: Samples, folder: Path, rng: np.random.Generator) -> Case:
    """An output path that is (or links to) an input: refused, the input untouched."""
    anim, clip, bvh = folder / "in.h5", folder / "clip.npz", folder / "clip.bvh"
    shutil.copy(samples.animation, anim)
    shutil.copy(samples.native, clip)
    shutil.copy(samples.bvh, bvh)
    (folder / "link.glb").symlink_to(anim)
    choices = {
        "export onto its input": (_cli("export", anim, "--to", "glb", "-o", anim), anim),
        "export pc2 onto its input": (_cli("export", anim, "--to", "pc2", "-o", anim), anim),
        "export through a link to its input": (
            _cli("export", anim, "-o", folder / "link.glb"),
            folder / "link.glb",
        ),
        "preview onto its input": (_cli("preview", anim, "-o", anim, "--size", 64, "--frames", 2), anim),
        "animate onto its motion": (_cli("animate", clip, "--model", samples.model, "-o", clip), clip),
        "features onto its motion": (_cli("motion", "features", bvh, "-o", bvh), bvh),
        "synth over a bvh": (_cli("motion", "synth", "walk", "-o", bvh), bvh),
        "animate onto the model": (
            _cli("animate", clip, "--model", samples.model, "-o", samples.model / "bundle.json"),
            samples.model / "bundle.json",
        ),
    }
    what = str(rng.choice(sorted(choices)))
    command, target = choices[what]
    case = Case(number, "output = input", what, command, target, [target.name])
    case.keep = {str(p): file_digest(p) for p in (anim, clip, bvh, samples.model / "bundle.json")}
    return case


def _interrupt_case(number: int, samples: Samples, out: Path, rng: np.random.Generator) -> Case:
    """Ctrl-C or SIGTERM while a command works: exit 130 / 143, nothing at the output, no temporary file."""
    sig = int(rng.choice([signal.SIGINT, signal.SIGTERM]))
    if rng.random() < 0.6:
        command, target = (
            _cli("animate", samples.native, "--model", samples.model, "-o", out / "out.h5"),
            out / "out.h5",
        )
    else:
        command, target = _cli("preview", samples.animation, "-o", out / "a.mp4", "--size", 96), out / "a.mp4"
    delay = float(rng.uniform(0.0, 1.5))
    case = Case(
        number,
        "interrupt",
        f"{signal.Signals(sig).name} {delay:.2f} s into {command[3]}",
        command,
        target,
        [target.name],
    )
    case.interrupt = (sig, delay)
    return case
