"""Analysis: does the collision push-out tear the cloth, and what does a character's push-out cost?

The push-out (hrr_garment/inference/collision.py) moves garment vertices out of the body; where it
moves one vertex far and its neighbours little, edges stretch and the strain limit has to undo
part of the push. This tool runs a trained model on a dataset's clips (its default mode, offline,
the push-out off), then the push-out under each setting asked for, and reports per setting:

- ``limited_frames_pct``: the frames on which the strain limit moved an edge (the issue's bar: at
  most 5 %), and ``torn_before_limit_pct``: the frames with an edge over its limit after the push
  alone (what the limit had to repair);
- ``strain_max`` / ``strain_p99``: edge length over rest length of the output (worst frame; p99
  over every edge of every frame), beside the unpushed output's and the simulation's;
- ``inside_after_pct``: vertices more than 5 mm inside the body after the push-out, and
  ``inside_before_pct`` before it (after the subspace push, in its rows);
- ``pve_mm``: the mean vertex error against the dataset's one simulation of each clip (one chaotic
  truth: it compares settings on the same frames, it does not rank models; hrr-eval does);
- ``us_per_character``: the push-out's median seconds per character-frame, frames pushed ``crowd``
  at a time as a crowd's step pushes its characters (report off, as a stream runs it), over
  ``repeat`` passes.

With ``--subspace-push`` every setting is also run after the push in the fast decoder's subspace
(:mod:`hrr_garment.inference.subspace_push`), its ``us_per_character`` the two together.

    python tools/studies/push_out_analysis.py --model hrr_work/models/dress-real-quick \\
        --dataset hrr_work/datasets/dress-real-quick.h5 --split test --follow 0 6 --slack 0 0.1 --sequences 12
    python tools/studies/push_out_analysis.py --model hrr_work/make-plain/model \\
        --dataset hrr_work/make-plain/dataset.h5 --split test --follow 0 --visible

``--visible`` pushes out of the mesh the model's body is drawn with (a character's own, an anny
body's), as ``hrr-animate`` does on such a body, instead of its capsules. The first setting also
pushes the simulation itself (``simulation, pushed``): what the truth asks of the push-out. In a
mode that adds to the regression (residual, detail: the default look), the push-out first
takes the additions back where they carry the cloth into the body, as the product's does
(:mod:`hrr_garment.inference.take_back`; not in the subspace rows, as the product's does not);
``--no-take-back`` pushes the cloth as it came, as the product did before. ``inside_before_pct`` is
of the cloth as it came either way.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from typing import NamedTuple

import numpy as np


def _timed_us(
    vertices: np.ndarray, motion, faces, common: dict, settings, crowd: int, repeat: int, body_of
) -> float:
    """Median microseconds per frame of the push-out (its subspace push included where
    ``settings`` has one), ``crowd`` frames a call (report off); ``body_of(motion)``: the body
    pushed out of, posed for those frames; ``common``: push_out's ``mean`` and ``limits``."""
    from hrr_garment.inference.collision import push_out

    per_frame = []
    for _ in range(repeat):
        for start in range(0, len(vertices) - crowd + 1, crowd):
            sl = slice(start, start + crowd)
            t0 = time.perf_counter()
            push_out(
                vertices[sl],
                motion.slice(start, start + crowd),
                faces,
                body=body_of(motion.slice(start, start + crowd)),
                settings=settings,
                mean=common["mean"],
                limits=common["limits"],
                report=False,
                base=None if common.get("base") is None else common["base"][sl],
            )
            per_frame.append((time.perf_counter() - t0) / crowd)
    return 1e6 * float(np.median(per_frame)) if per_frame else float("nan")


def body_of_model(animator, visible: bool):
    """``body_of(motion)``: what the push-out pushes out of, posed for ``motion``: the model's body's
    capsules, or (``visible``) the mesh it is drawn with (:class:`~hrr_garment.inference.visible_push.
    PosedSkin`: the push-out hrr-animate runs on an anny body or a fitted character)."""
    body = animator.body()
    if not visible:
        return lambda motion: body.body
    from hrr_garment.inference.visible_push import PosedSkin

    collider = body.visible_collider()
    if collider is None:
        raise SystemExit(
            "--visible: the model's body has no mesh of its own (the mannequin is drawn as its capsules)"
        )
    return lambda motion: PosedSkin.of(collider, motion)


def inside_pct(frames: np.ndarray, out: np.ndarray, motion, body, report) -> tuple:
    """Each frame's share of vertices more than 5 mm inside ``body`` before and after the push:
    against capsules measured here, against a mesh (a ``PosedSkin``) the push-out's own ``report``
    (its means, per frame)."""
    from hrr_garment.sim.quality import body_signed_distance

    if report is None:
        return tuple((body_signed_distance(x, motion, body) < -0.005).mean(1) for x in (frames, out))
    return np.full(len(frames), report.inside_before), np.full(len(frames), report.inside_after)


def regression_under(animator, motion, mode: str | None) -> np.ndarray | None:
    """The regression's cloth under ``mode``'s additions (offline, not pushed), or None where the
    mode has none to take back (all but the residual and the detail mode)."""
    from hrr_garment.inference.modes import Mode

    resolved = animator.resolve(None, **({"mode": mode} if mode else {}))
    if resolved.mode not in (Mode.RESIDUAL, Mode.DETAIL):
        return None
    return animator.animate(motion, push_out=False, mode="regression").vertices


def push_out_rows(follows: list[int], slope: float, slacks: list[float]) -> dict:
    """The push-out settings compared, by label: each follow with each slack."""
    from hrr_garment.inference.collision import PUSH_OUT

    return {
        f"follow {f}, slack {k:g}": dataclasses.replace(
            PUSH_OUT, follow=f, follow_slope=slope, stretch_slack=k
        )
        for f in follows
        for k in slacks
    }


class Asked(NamedTuple):
    """How the cloth is made and pushed: the ``mode`` animated (None: the model's default, which a
    retrained stage may have reset), each setting also after the push in the fast decoder's subspace
    (``subspace_push``), out of the mesh the model's body is drawn with (``visible``) or its capsules."""

    mode: str | None = None
    subspace_push: bool = False
    visible: bool = False
    take_back: bool = True  # the mode's additions taken back first, as the product's push-out does


def analyse(
    model: str, dataset: str, split: str, rows: dict, sequences: int, timing: tuple[int, int], asked=Asked()
) -> dict:
    """``rows``: label -> :class:`~hrr_garment.inference.collision.PushOutSettings` (:func:`push_out_rows`);
    ``timing``: (crowd, repeat) of the timed pushes; ``asked``: :class:`Asked`. The first row is also
    run on the simulation itself (``"simulation, pushed"``): what the truth asks of the push-out."""
    crowd, repeat = timing
    mode, subspace_push, visible = asked.mode, asked.subspace_push, asked.visible
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.inference.animator import Animator
    from hrr_garment.inference.collision import push_out
    from hrr_garment.inference.strain_limit import limit_push_strain
    from hrr_garment.sim.quality import edge_strain

    animator = Animator.load(model)
    ds = GarmentDataset(dataset)
    names = ds.splits[split][:sequences]
    faces, rest, edges = ds.template.faces, ds.template.vertices, ds.template.edges()
    body, body_of = animator.body().body, body_of_model(animator, visible)
    subspace = animator.subspace_push if subspace_push else None
    if subspace_push and subspace is None:
        raise SystemExit(f"{model}: no fast decoder (subspace) to push in")
    variants = [(label, settings, None) for label, settings in rows.items()]
    variants += (
        [(f"{label}, subspace push", settings, subspace) for label, settings in rows.items()]
        if subspace
        else []
    )
    truth_label, truth_settings = "simulation, pushed", next(iter(rows.values()))
    found = {
        k: {"limited": [], "torn": [], "strain": [], "inside": [], "before": [], "pve": [], "us": []}
        for k in [label for label, _, _ in variants] + [truth_label]
    }
    plain = {"unpushed": [], "simulation": []}
    unpushed_pve = []
    for name in names:
        record = ds.sequence(name)
        anim = animator.animate(record.motion, push_out=False, **({"mode": mode} if mode else {}))
        base = regression_under(animator, record.motion, mode) if asked.take_back else None
        # strain against the garment at rest on the sequence's own body (a carried garment's edges
        # are not the template's)
        at_rest = rest if record.dressed is None else record.dressed.garment.vertices
        plain["unpushed"].append(edge_strain(anim.vertices, at_rest, edges))
        plain["simulation"].append(edge_strain(record.garment, at_rest, edges))
        unpushed_pve.append(np.linalg.norm(anim.vertices - record.garment, axis=-1).mean(1))
        pushed_body = body_of(record.motion)
        moved_in = pushed_body if visible else (*body.pose_motion(record.motion), body.radii)
        # the strain limit measures the garment as it rests on that body, as the product's push does
        common = {
            "body": pushed_body,
            "mean": animator.smoothing,
            "limits": animator.edge_limits.on_bodies(at_rest),
        }
        cases = [(label, settings, push, anim.vertices, base) for label, settings, push in variants]
        cases.append((truth_label, truth_settings, None, record.garment.astype(np.float32), None))
        # the push alone (its follow included), then with its strain limit
        for label, settings, push, cloth, under in cases:
            # the subspace move measures the body pushed out of: the mesh the viewer sees, or the capsules;
            # the push-out takes back no additions before it (decision 0046)
            frames = cloth if push is None else push(cloth, record.motion, moved_in, settings.margin)
            common["base"] = under if push is None else None
            bare, _ = push_out(
                frames,
                record.motion,
                faces,
                settings=dataclasses.replace(settings, max_strain=np.inf),
                report=False,
                **common,
            )
            _, torn = limit_push_strain(
                bare, frames, common["limits"], settings.max_strain, slack=settings.stretch_slack
            )
            # against a mesh the push-out's own report measures the cloth inside (in the kernel)
            out, measured = push_out(
                frames, record.motion, faces, settings=settings, report=visible, **common
            )
            before, inside = inside_pct(
                cloth if push is not None else frames,
                out,
                record.motion,
                pushed_body,
                measured if visible else None,
            )
            found[label]["torn"].append(torn)
            found[label]["limited"].append(np.abs(out - bare).max((1, 2)) > 0)
            found[label]["strain"].append(edge_strain(out, at_rest, edges))
            found[label]["before"].append(before)
            found[label]["inside"].append(inside)
            found[label]["pve"].append(np.linalg.norm(out - record.garment, axis=-1).mean(1))
            if label != truth_label:
                timed = settings if push is None else dataclasses.replace(settings, subspace=push)
                found[label]["us"].append(
                    _timed_us(
                        cloth, record.motion, faces, common, timed, crowd, repeat, body_of
                    )  # with its base
                )
    report = {
        "model": model,
        "mode": mode or "default",
        "dataset": dataset,
        "split": split,
        "body": "visible" if visible else "capsules",
        "sequences": names,
        "crowd": crowd,
        "rows": summarised(found, plain, unpushed_pve),
    }
    return report


def summarised(found: dict, plain: dict, unpushed_pve: list) -> dict:
    """Each row's figures from the per-sequence arrays ``analyse`` gathered."""
    rows = {}
    for label, f in found.items():
        strain = np.concatenate(f["strain"])
        rows[label] = {
            "limited_frames_pct": round(100 * float(np.concatenate(f["limited"]).mean()), 2),
            "torn_before_limit_pct": round(100 * float(np.concatenate(f["torn"]).mean()), 2),
            "strain_max": round(float(strain.max()), 3),
            "strain_p99": round(float(np.percentile(strain, 99)), 4),
            "inside_before_pct": round(100 * float(np.concatenate(f["before"]).mean()), 3),
            "inside_after_pct": round(100 * float(np.concatenate(f["inside"]).mean()), 3),
            "pve_mm": round(1000 * float(np.concatenate(f["pve"]).mean()), 2),
            "us_per_character": round(float(np.median(f["us"])), 1) if f["us"] else None,
        }
    for label, strains in plain.items():
        strain = np.concatenate(strains)
        rows[label] = {
            "strain_max": round(float(strain.max()), 3),
            "strain_p99": round(float(np.percentile(strain, 99)), 4),
        }
    rows["unpushed"]["pve_mm"] = round(1000 * float(np.concatenate(unpushed_pve).mean()), 2)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", required=True)
    parser.add_argument("--dataset", required=True)
    parser.add_argument("--split", default="test")
    parser.add_argument(
        "--follow", type=int, nargs="+", default=[0, 6], help="neighbour-follow passes to compare"
    )
    parser.add_argument("--slope", type=float, default=0.25, help="the follow's slope (of the rest distance)")
    parser.add_argument(
        "--slack",
        type=float,
        nargs="+",
        default=[0.1],
        help="the strain limit's slack over an edge the decoder stretched (of the rest length)",
    )
    parser.add_argument("--sequences", type=int, default=12, help="the split's first N clips")
    parser.add_argument(
        "--crowd", type=int, default=32, help="frames per timed push-out call (a crowd's characters)"
    )
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument(
        "--subspace-push",
        action="store_true",
        help="each setting also after the push in the fast decoder's subspace",
    )
    parser.add_argument("--mode", help="the mode animated (default: the model's own default mode)")
    parser.add_argument(
        "--visible",
        action="store_true",
        help="push out of the mesh the model's body is drawn with (an anny body, a fitted character), "
        "not its capsules",
    )
    parser.add_argument(
        "--no-take-back",
        action="store_true",
        help="push the cloth as it came: the mode's additions not taken back first (the product's before)",
    )
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    report = analyse(
        args.model,
        args.dataset,
        args.split,
        push_out_rows(args.follow, args.slope, args.slack),
        args.sequences,
        (args.crowd, args.repeat),
        Asked(args.mode, args.subspace_push, args.visible, not args.no_take_back),
    )
    if args.json:
        print(json.dumps(report))
        return
    print(
        f"{args.model} on {len(report['sequences'])} {args.split} clips of {args.dataset} "
        f"({args.mode or 'default'} mode, offline; pushed out of the body's {report['body']}):"
    )
    for label, row in report["rows"].items():
        print(f"  {label}: " + ", ".join(f"{k} {v}" for k, v in row.items()))


if __name__ == "__main__":
    main()
