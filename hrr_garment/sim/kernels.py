"""Warp kernels of the newton scene (imported only with the ``sim`` extra, by :mod:`.scene`)."""

from __future__ import annotations

import warp as wp


@wp.kernel
def scatter_positions(
    values: wp.array(dtype=wp.vec3), index: wp.array(dtype=wp.int32), positions: wp.array(dtype=wp.vec3)
):
    """``positions[index[i]] = values[i]``: the pinned vertices written on the device, without
    reading every particle back to the host each substep (megabytes per substep in a GPU batch)."""
    i = wp.tid()
    positions[index[i]] = values[i]
