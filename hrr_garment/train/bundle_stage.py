"""What a stage that adds a part to a trained bundle starts from (the baseline, the fast decoder):
the bundle and its dataset, checked to belong together."""

from __future__ import annotations

from pathlib import Path

from ..artifacts.bundle import Bundle
from ..artifacts.bundle_loader import load_bundle
from ..data.dataset import DatasetError, GarmentDataset


def bundle_and_dataset(
    folder: Path, dataset: str | Path, cache_dir: Path | None
) -> tuple[Bundle, GarmentDataset]:
    """The bundle in ``folder`` (the code-space stage must have written it) and ``dataset``; a
    DatasetError where the dataset is not of the model's garment and template."""
    bundle = load_bundle(folder, cache_dir)
    ds = GarmentDataset(dataset)
    if ds.garment != bundle.garment or ds.template.num_vertices != bundle.template.num_vertices:
        raise DatasetError(
            dataset,
            f"is not the dataset of the model in {folder} ({bundle.garment}, "
            f"{bundle.template.num_vertices} vertices)",
        )
    return bundle, ds
