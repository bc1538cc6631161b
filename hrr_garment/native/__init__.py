"""Fused C kernels (the C sources in this folder, :mod:`.build` lists them), compiled on first use,
and their ctypes glue. The ground floor of the package: it imports nothing of hrr_garment but
:mod:`hrr_garment.paths` (where the compiled library is cached).

- :mod:`.build`: the compiler driver, the cache and the loaded library's ctypes table
  (:func:`load_kernel`; without a compiler, or with ``HRR_NATIVE=0``, None and callers use the
  PyTorch path);
- :mod:`.threads`: the kernels' thread count and the pinning of their workers;
- :mod:`.panels`: the dense products' panel layout;
- :mod:`.decoder`: the mesh decoder's blocks, its single-frame form (streaming) and its bfloat16
  form on AMX;
- :mod:`.capsules`: the capsule-body signed distance (:mod:`hrr_garment.body`);
- :mod:`.skin`: the signed distance to the skinned mesh by inverse skinning
  (:mod:`hrr_garment.body.skin_collider`'s query);
- :mod:`.body`: the push-out and its strain limit of :mod:`hrr_garment.inference.collision`
  (their structs: :mod:`.kernel_structs`);
- :mod:`.motion`: forward kinematics, causal motion features and body-frame points into the
  world (:mod:`hrr_garment.motion`).

The code space's window step (:mod:`hrr_garment.models.native_codes`) calls the library directly.
The names below are re-exported for the package's callers.
"""

from __future__ import annotations

from .build import FLAGS, HEADERS, SOURCE, SOURCES, load_kernel
from .decoder import PRECISIONS
from .motion import body_to_world, causal_features, forward_kinematics
from .panels import PANEL, pack_panels
from .threads import default_threads, pin_workers

__all__ = [
    "FLAGS",
    "HEADERS",
    "PANEL",
    "PRECISIONS",
    "SOURCE",
    "SOURCES",
    "body_to_world",
    "causal_features",
    "default_threads",
    "forward_kinematics",
    "load_kernel",
    "pack_panels",
    "pin_workers",
]
