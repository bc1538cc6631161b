"""The push-out's argument structs (``push_out.h``) as ctypes structures (what :mod:`.body`'s
push-out and strain limit fill in for the kernel): the push's settings, the subspace move's arrays
and settings, and the strain limit's edge arrays and settings. Field order and types follow the C
declarations."""

from __future__ import annotations

import ctypes


class PushArgs(ctypes.Structure):
    """push_out.h's PushArgs."""

    _fields_ = [
        ("margin", ctypes.c_double),
        ("smooth", ctypes.c_int),
        ("rounds", ctypes.c_int),
        ("depth", ctypes.c_double),
    ]


class SubspaceArgs(ctypes.Structure):
    """push_out.h's SubspaceArgs."""

    _fields_ = [
        ("basis", ctypes.c_void_p),
        ("blocks", ctypes.c_void_p),
        ("stretch", ctypes.c_void_p),
        ("k", ctypes.c_int),
        ("iterations", ctypes.c_int),
        ("strain_weight", ctypes.c_double),
        ("ridge", ctypes.c_double),
        ("clearance", ctypes.c_double),
    ]


class StrainArgs(ctypes.Structure):
    """push_out.h's StrainArgs."""

    _fields_ = [
        ("edges", ctypes.c_void_p),
        ("rest", ctypes.c_void_p),
        ("colour", ctypes.c_void_p),
        ("colour_ptr", ctypes.c_void_p),
        ("ve_ptr", ctypes.c_void_p),
        ("ve_idx", ctypes.c_void_p),
        ("E", ctypes.c_int),
        ("colours", ctypes.c_int),
        ("iterations", ctypes.c_int),
        ("max_strain", ctypes.c_double),
        ("slack", ctypes.c_double),
        ("tol", ctypes.c_double),
        ("omega", ctypes.c_double),
        ("rest_row", ctypes.c_void_p),
    ]
