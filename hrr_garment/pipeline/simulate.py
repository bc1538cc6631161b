"""The ``simulate`` stage of training (:func:`~.train.train_model`): a preset's dataset built, or
made again where the preset has changed since (finished sequences are reused)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..sim.preset import Preset


def dataset_out_of_date(dataset: Path, preset: Preset) -> str | None:
    """Why an existing dataset of the preset's own clips is not what the preset makes now, or None:
    none yet, a dataset of other clips (``hrr-simulate --motions``, another preset: the user's
    choice), or one made as the preset stands. A dataset records the preset's settings that decide
    its sequences (:func:`~hrr_garment.sim.preset.plan_record`); one made before it did is compared
    by its sequences' names (:func:`missing_sequences`), and, where the preset places clips on bodies
    or adds splices (neither shows in the planned names), taken as out of date."""
    from ..sim.preset import plan_record

    ds = _own_dataset(dataset, preset)
    if ds is None:
        return None
    if "plan" in ds.info:
        now = plan_record(preset)
        changed = [k for k in now if ds.info["plan"].get(k) != now[k]]
        return (
            f"was made with other {', '.join(changed)} settings than the {preset.name} preset's"
            if changed
            else None
        )
    missing = _missing_names(ds, preset)
    if missing:
        return f"lacks {len(missing)} of the {preset.name} preset's sequences (e.g. {missing[0]})"
    if preset.bodies or preset.splices:
        return f"predates the record of the {preset.name} preset's bodies and splices it was made with"
    return None


def missing_sequences(dataset: Path, preset: Preset) -> list[str]:
    """The preset's sequences that an existing dataset of its own clips does not hold: a workspace
    made with an earlier, smaller version of the preset, or one whose mirrors are reflections where
    the preset now simulates them (docs/dataset.md: a reflection is not the mirrored motion's
    simulation). None where there is no dataset yet, or where it holds other clips (``hrr-simulate
    --motions``, or a different preset): that one is the user's choice."""
    ds = _own_dataset(dataset, preset)
    return [] if ds is None else _missing_names(ds, preset)


def _own_dataset(dataset: Path, preset: Preset):
    """The dataset at ``dataset`` (a :class:`~hrr_garment.data.dataset.GarmentDataset`) where it was
    made by ``preset`` from the preset's own clips; None where there is none, or it holds other clips
    or other cloths (``hrr-simulate --material`` on a preset with a materials section)."""
    if not dataset.exists():
        return None
    from ..data.dataset import GarmentDataset

    ds = GarmentDataset(dataset)
    own = ds.info.get("preset") == preset.name and not (ds.info.get("motions") or ds.info.get("in_one_cloth"))
    return ds if own else None


def _missing_names(ds, preset: Preset) -> list[str]:
    """:func:`missing_sequences` of an open dataset of the preset's own clips."""
    from ..data.splits import MIRROR_SUFFIX
    from ..sim.augment import AUGMENT_PREFIXES
    from ..sim.plan import plan_sequences
    from ..sim.preset import mirror_mode

    planned = [spec.name for spec in plan_sequences(preset)]
    mirror = mirror_mode(preset.mirror)
    mirrors = [f"{name}{MIRROR_SUFFIX}" for name in planned] if mirror else []
    held = {
        n for n in ds.names if not n.startswith(AUGMENT_PREFIXES)
    }  # splices and the like are planned by the build
    if not held <= set(planned + mirrors):  # other clips under the preset's name: the user's choice
        return []
    # files written before mirrors were simulated record ``true`` for their reflections
    made = ds.info.get("augmentation", {}).get("mirror")
    reflected = made is True or made == "reflect"
    stale = set(mirrors) if reflected and mirror == "simulate" else set()
    return [name for name in planned + mirrors if name not in held or name in stale]


@dataclass(frozen=True)
class SimulatedDataset:
    """What the ``simulate`` stage built: the build's report and the garment simulated."""

    report: object  # :class:`~hrr_garment.sim.build.BuildReport`
    mesh: object  # :class:`~hrr_garment.garment.mesh.GarmentMesh`


def simulate_preset(garment: str, preset: Preset, out: Path, progress: bool = True) -> SimulatedDataset:
    """Simulate ``preset``'s sequences of ``garment`` into the dataset ``out`` (as hrr-simulate
    would; finished sequences are reused)."""
    from ..export.preview import write_dataset_preview
    from ..garment.templates import make_garment
    from ..sim.body_plan import choose_bodies
    from ..sim.build import BuildSettings, build_dataset
    from ..sim.material_plan import choose_materials
    from ..sim.plan import build_options, plan_sequences
    from ..sim.simulator import SimSettings

    mesh = make_garment(garment, preset.vertices)
    choice = choose_bodies(
        plan_sequences(preset), mesh, preset_bodies=preset.bodies, where=preset.name, progress=progress
    )
    cloths = choose_materials(choice.specs, preset.materials, preset.name)
    options = build_options(preset, cloths.specs)
    options["info"]["garment_vertices"] = mesh.num_vertices
    if choice.bodies:
        options["info"]["bodies"] = choice.info
    if cloths.materials:
        options["info"]["materials"] = cloths.info
    report = build_dataset(
        mesh,
        cloths.specs,
        SimSettings.from_dict(preset.sim),
        out=out,
        options=BuildSettings(
            progress=progress,
            preview=write_dataset_preview,
            bodies=choice.bodies,
            hold_out_bodies=choice.hold_out,
            hold_out_materials=cloths.hold_out,
            **options,
        ),
    )
    return SimulatedDataset(report, mesh)
