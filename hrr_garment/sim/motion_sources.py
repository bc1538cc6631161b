"""Where the motion a build reads comes from: each motion file's source (its licence:
:mod:`hrr_garment.motion.licences`), and a sequence's, for the dataset's record."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from ..motion.licences import OWN, PROCEDURAL, SOURCES, entry_source
from ..motion.synth import KINDS
from .preset import Preset
from .sources import resolve_motion_entries

if TYPE_CHECKING:
    from .plan import SequenceSpec


def sourced_entries(preset: Preset, motions: list[str] | None) -> tuple[list[tuple[str, str]], list[str]]:
    """The motion entries a build reads, each with its source (motion/licences.py): ``--motions``'
    files where given, else the preset's; and the entries a ``commercial_only`` preset leaves out."""
    if motions:
        entries = [(item, entry_source(item)) for item in motions if item not in KINDS]
    else:
        entries = [
            (e, entry_source(e)) if isinstance(e, str) else (e["path"], entry_source(e["path"], e["source"]))
            for e in preset.motions
        ]
    if not preset.commercial_only:
        return entries, []
    return [e for e in entries if SOURCES[e[1]].commercial], [
        e for e, s in entries if not SOURCES[s].commercial
    ]


def file_sources(preset: Preset, motions: list[str] | None = None) -> dict[str, str]:
    """Every motion file a build reads (``--motions``' files where given, else the preset's), in
    order, each with the source of the entry that named it first."""
    entries, _ = sourced_entries(preset, motions)
    base = Path(preset.base) if preset.base and not motions else None
    sources: dict[str, str] = {}
    for entry, source in entries:
        for path in resolve_motion_entries([entry], base):
            sources.setdefault(str(path), source)
    return sources


def spec_sources(spec: SequenceSpec, files: dict[str, str]) -> str:
    """The source of a sequence's motion: procedural, or its file's (``a+b`` for a splice of files
    from two sources); a file no entry named is the user's own."""
    if spec.kind != "file":
        return PROCEDURAL
    found = [files.get(spec.path, OWN)] + ([files.get(spec.upper_path, OWN)] if spec.upper_path else [])
    return "+".join(sorted(set(found)))
