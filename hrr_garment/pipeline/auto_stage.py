"""The auto mode's calibration after the code-space stage (:func:`calibrate_auto`): on the
dataset's validation clips, recorded in bundle.json, and calibrated or picked again only where
what it was recorded under changed."""

from __future__ import annotations

from pathlib import Path

from ..artifacts.auto_calibration import AutoCalibration
from ..eval.auto_criterion import AutoSettings, repick
from ..eval.auto_mode import calibrate_auto_mode, measure_again
from ..eval.auto_outdated import (
    followed_otherwise,
    lacks_default_body,
    lacks_free_cloth,
    lacks_free_folds,
    lacks_sample,
    lacks_swing,
    swing_unmeasured,
)


def calibrate_auto(
    folder: str | Path, dataset: str | Path, progress: bool = True, config: AutoSettings = AutoSettings()
) -> AutoCalibration:
    """The mode ``auto`` runs (:mod:`hrr_garment.eval.auto_mode`), calibrated on the dataset's
    validation clips once per bundle and recorded in bundle.json with every candidate's numbers;
    the recorded one where it was, picked again from its numbers where ``config``'s allowance differs
    from the one it was picked under (the swing gains of a first pick that moved measured first)."""
    from ..artifacts.typed_manifest import read_manifest, update_manifest
    from ..inference.animator import Animator

    manifest = read_manifest(folder)  # reading it hashes every file: once
    recorded = manifest.auto
    # calibrated again where recorded before the candidates carried their cloth inside the body (the
    # criterion counts it), the residual or the folds on free cloth, the default body's clips apart,
    # the folds followed in time (as the detail mode now runs) or the swing's gain; the sample mode
    # measured where the model gained it since; picked again where only an allowance moved
    if (
        recorded is None
        or any("penetration_pct" not in c for c in (recorded.candidates or {}).values())
        or lacks_swing(recorded)
        or lacks_free_cloth(recorded, manifest.residual)
        or lacks_default_body(recorded, manifest.bodies)
        or (manifest.folds is not None and (followed_otherwise(recorded) or lacks_free_folds(recorded)))
    ):
        auto = calibrate_auto_mode(
            Animator.load(folder), _validation_records(dataset), config, progress=progress
        )
    elif lacks_sample(recorded, manifest.sampler) or swing_unmeasured(recorded, config):
        auto = measure_again(
            Animator.load(folder),
            _validation_records(dataset),
            auto=recorded,
            config=config,
            new=("sample",) if lacks_sample(recorded, manifest.sampler) else (),
            progress=progress,
        )
    elif any(getattr(recorded, key) != value for key, value in config.limits().items()):
        auto = repick(recorded, config)
    else:
        return recorded
    update_manifest(folder, auto=auto)
    return auto


def _validation_records(dataset: str | Path) -> list:
    """The dataset's validation sequences (what the auto mode is calibrated on)."""
    from ..data.dataset import GarmentDataset

    ds = GarmentDataset(dataset)
    return [ds.sequence(n) for n in ds.splits.get("val", [])]
