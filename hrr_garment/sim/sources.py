"""Motion files a preset names: files, globs, folders and archives, and the clip group of each.

An entry is a path, a glob (``cmu/*.bvh``), a folder (every BVH / npz below it) or an archive
(``.tar``, ``.tar.gz``, ``.tar.xz``, ``.zip``: unpacked once into the workspace, never into the
repository, and read from there after). ``mocap:REST`` resolves against the shared mocap folder
(``$HRR_MOCAP_DIR`` or ``shared/data/mocap`` beside the checkout); other relative entries resolve
against the preset's folder first, then the working directory.

Clips are grouped for splits by a named field of a file-name pattern (a Bandai clip
``dataset-1_walk_proud_001`` has content ``walk`` and style ``proud``); a file the pattern does
not match is a group of its own. Whole groups go to validation or test, never single frames.
"""

from __future__ import annotations

import glob as globlib
import re
import shutil
import tarfile
import tempfile
import zipfile
from pathlib import Path

from ..errors import InputError
from ..paths import find_mocap_dir, workspace

MOTION_SUFFIXES = (
    ".bvh",
    ".npz",
    ".glb",
    ".gltf",
    ".fbx",
)  # a glTF file gives its first animation; FBX needs Blender
ARCHIVE_SUFFIXES = (".tar", ".tar.gz", ".tgz", ".tar.xz", ".txz", ".zip")
# <source>_<content>_<style>_<take>, as the Bandai-Namco library names its clips.
DEFAULT_NAME_PATTERN = r"(?P<source>[^_]+)_(?P<content>[^_]+)_(?P<style>[^_]+)_(?P<take>\d+)"


def _is_archive(path: Path) -> bool:
    return path.name.lower().endswith(ARCHIVE_SUFFIXES)


def _archive_stem(path: Path) -> str:
    name = path.name
    for suffix in sorted(ARCHIVE_SUFFIXES, key=len, reverse=True):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return path.stem


def unpacked_archive(archive: Path) -> Path:
    """The folder holding ``archive``'s files, unpacked under ``workspace()/mocap`` on first use.

    Unpacked into a temporary folder beside the target and renamed, so a killed unpack leaves
    nothing that a later run would take for finished. The folder is keyed by the archive's name
    and size: a different archive of the same name unpacks afresh.
    """
    target = workspace() / "mocap" / f"{_archive_stem(archive)}-{archive.stat().st_size}"
    if target.is_dir():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        if archive.name.lower().endswith(".zip"):
            with zipfile.ZipFile(archive) as z:
                for member in z.namelist():  # no absolute paths or '..' out of the folder
                    if Path(member).is_absolute() or ".." in Path(member).parts:
                        raise InputError(archive, f"archive member {member!r} would land outside the folder")
                z.extractall(tmp)
        else:
            with tarfile.open(archive) as tar:
                tar.extractall(tmp, filter="data")  # refuses links and paths out of the folder
        tmp.rename(target)
    except (OSError, tarfile.TarError, zipfile.BadZipFile) as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if target.is_dir():  # another process unpacked it first
            return target
        raise InputError(archive, f"cannot unpack the motion archive: {exc}") from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return target


def _motion_files_below(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file() and p.suffix.lower() in MOTION_SUFFIXES)


def _anchor(entry: str, base: Path | None) -> str:
    """The entry as an absolute path pattern (``mocap:`` prefix, preset folder, working directory)."""
    if entry.startswith("mocap:"):
        mocap = find_mocap_dir()
        if mocap is None:
            raise InputError(entry, "the shared mocap folder was not found; set HRR_MOCAP_DIR")
        return str(mocap / entry[len("mocap:") :])
    path = Path(entry).expanduser()
    if path.is_absolute():
        return str(path)
    if base is not None and globlib.glob(str(base / entry), recursive=True):
        return str(base / entry)
    return str(Path.cwd() / entry)


def resolve_motion_entries(entries: list[str], base: Path | None = None) -> list[Path]:
    """Every motion file the entries name, each once, in the order given (sorted within an entry)."""
    files: list[Path] = []
    for entry in entries:
        matches = sorted(Path(p) for p in globlib.glob(_anchor(entry, base), recursive=True))
        if not matches:
            raise InputError(
                entry,
                "names no file or folder (paths resolve against the preset's folder, "
                "then the working directory; mocap:PATH against the shared mocap folder)",
            )
        for match in matches:
            if match.is_dir():
                found = _motion_files_below(match)
            elif _is_archive(match):
                found = _motion_files_below(unpacked_archive(match))
            elif match.suffix.lower() in MOTION_SUFFIXES:
                found = [match]
            else:
                continue
            if not found:
                raise InputError(match, f"holds no motion files ({', '.join(MOTION_SUFFIXES)})")
            files += [f.resolve() for f in found]
    seen: set[Path] = set()
    return [f for f in files if not (f in seen or seen.add(f))]


def clip_group(stem: str, by: str | None, pattern: str = DEFAULT_NAME_PATTERN) -> str:
    """The group a clip named ``stem`` belongs to for splitting: ``by`` field of ``pattern``, else
    the stem."""
    if by is None:
        return stem
    match = re.fullmatch(pattern, stem)
    if match is None or by not in match.groupdict():
        return stem
    return f"{by}={match.group(by)}"
