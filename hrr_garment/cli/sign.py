"""hrr-sign: sign model bundles that travel between people, and check them (the ``sign`` extra).

    hrr-sign keygen -o studio.key                 # studio.key (private, keep it) and studio.pub (share it)
    hrr-sign sign hrr_work/models/dress --key studio.key
    hrr-sign verify hrr_work/models/dress         # exit 0: valid signature, and by which key
    HRR_TRUSTED_KEYS=studio.pub HRR_REQUIRE_SIGNATURE=1 hrr-animate clip.bvh --model dress -o out.h5

A signature covers bundle.json, which records the SHA-256 of every other file of the bundle. On
load, a signature that does not verify is refused; with HRR_TRUSTED_KEYS set, an unsigned bundle
or one signed by another key loads with a warning, or is refused under HRR_REQUIRE_SIGNATURE=1.
See docs/reliability.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from ..artifacts.signature import SIGNATURE_FILE, generate_key, sign_bundle, verify_signature
from ..artifacts.typed_manifest import read_manifest
from ..errors import InputError
from ..io_utils import refuse_input_as_output
from ._common import run_cli


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hrr-sign", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = p.add_subparsers(dest="command", required=True)
    k = sub.add_parser("keygen", help="a new key pair: PRIVATE and PRIVATE with the suffix .pub")
    k.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="the private key's file (the public key goes beside it)",
    )
    s = sub.add_parser("sign", help="sign a model bundle (writes bundle.sig into it)")
    s.add_argument("model", type=Path)
    s.add_argument("--key", type=Path, required=True, help="the private key from hrr-sign keygen")
    v = sub.add_parser("verify", help="check a model bundle's signature")
    v.add_argument("model", type=Path)
    return p


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    if args.command == "keygen":
        public = args.output.with_suffix(".pub")
        for path in (args.output, public):
            if path.exists():
                raise InputError(path, "already exists: a key is never overwritten (choose another name)")
        generate_key(args.output)
        print(
            f"wrote {args.output} (private: keep it to yourself) and {public} (public: give it to those who "
            "load your models)"
        )
        return 0
    read_manifest(args.model, trust=False)  # a bundle whose files match their hashes before anything else
    if args.command == "sign":
        refuse_input_as_output(args.model / SIGNATURE_FILE, [args.key])
        key = sign_bundle(args.model, args.key)
        print(f"wrote {args.model / SIGNATURE_FILE} (key {key})")
        return 0
    check = verify_signature(args.model, (args.model / "bundle.json").read_bytes())
    if not check.signed:
        raise InputError(args.model, f"not signed (no {SIGNATURE_FILE})")
    print(f"{args.model}: signature valid, key {check.key}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-sign``; returns the exit status."""
    return run_cli(_main, argv, "hrr-sign")


if __name__ == "__main__":
    sys.exit(main())
