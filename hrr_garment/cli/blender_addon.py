"""hrr-blender-addon: write the Blender add-on that imports hrr-export's files right.

    hrr-blender-addon -o hrr_garment_blender.zip

Then in Blender (4.2 or later): Edit > Preferences > Get Extensions > Install from Disk, pick the
zip; File > Import > hrr_garment animation (.glb, .usd, .pc2). See docs/export.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from ..io_utils import require_suffix
from ._common import run_cli


def _main(argv: Sequence[str] | None) -> int:
    p = argparse.ArgumentParser(
        prog="hrr-blender-addon", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument(
        "-o", "--output", type=Path, default=Path("hrr_garment_blender.zip"), help="the zip to write"
    )
    args = p.parse_args(argv)
    from ..export.blender_package import write_addon_zip

    require_suffix(args.output, (".zip",), "the add-on")
    path = write_addon_zip(args.output)
    print(
        f"wrote {path}: install it in Blender 4.2+ (Edit > Preferences > Get Extensions > Install from Disk)"
    )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-blender-addon``; returns the exit status."""
    return run_cli(_main, argv, "hrr-blender-addon")


if __name__ == "__main__":
    sys.exit(main())
