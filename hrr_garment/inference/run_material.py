"""The cloth a run animates, checked against the model (:func:`run_material`).

A model trained in several cloths reads the cloth's values beside the body's measures
(:mod:`hrr_garment.garment.material_range`) and animates any cloth within the range it was trained
in; a model trained in one cloth animates that cloth and refuses another, as a model refuses a
body unlike its training bodies (:mod:`.character_body`). Without a cloth asked for, the model's
default (:attr:`~hrr_garment.artifacts.bundle.Bundle.default_material`).
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import InputError
from ..garment.material import Material, material_from
from ..garment.material_range import material_vector


class MaterialOutsideRange(InputError):
    """A cloth unlike any the model was trained in."""


def run_material(
    bundle, material: object = None, allow_outside: bool = False, where: str = "material"
) -> Material | None:
    """The cloth a run of ``bundle`` animates: ``material`` (a :class:`Material`, a fabric's name or
    values as ``--material`` takes them, a mapping) checked against the model's range of cloths, or
    the model's default where None (None for a model from before cloths were recorded). Outside the
    range: :class:`MaterialOutsideRange` naming each value and its range, or, with
    ``allow_outside``, a warning. Errors name ``where`` (the option or file the cloth came from)."""
    if material is None:
        return bundle.default_material
    cloth = material_from(material, where)
    known = bundle.material_range
    if known is None:
        raise InputError(
            where,
            f"the model in {bundle.folder} was trained before cloths were recorded: it animates the "
            "cloth it learned and cannot take another (train it again to choose the cloth)",
        )
    outside = known.outside(material_vector(cloth))
    if outside:
        count = known.cloths
        message = (
            f"cloth {cloth.name!r} is unlike the {count} cloth{'' if count == 1 else 's'} the model was "
            f"trained in: {'; '.join(outside)}"
        )
        if not allow_outside:
            hint = (
                "train in cloths like it" if count > 1 else "this model knows one cloth: train across cloths"
            )
            raise MaterialOutsideRange(where, f"{message} ({hint}, or allow it and expect a guess)")
        warnings.warn(message + "; animating it anyway", stacklevel=3)
    return cloth


def material_columns(bundle, materials: Material | list[Material] | None) -> np.ndarray | None:
    """What the model reads of the cloth: (m,) one cloth's values, or (n, m) one per character; None
    for a model of one cloth (it reads none)."""
    if not bundle.codespace.config.material_features:
        return None
    if isinstance(materials, Material):
        return material_vector(materials)
    if materials is None or any(m is None for m in materials):
        raise ValueError("a model across cloths needs each character's cloth")
    return np.stack([material_vector(m) for m in materials])


def cloth_columns(bundle, material: object, allow_outside: bool = False) -> np.ndarray | None:
    """A character's cloth as the model reads it: ``material`` checked (:func:`run_material`), then
    its values (:func:`material_columns`); None for a model of one cloth (the cloth is checked,
    nothing more). What a crowd's ``set_material`` keeps."""
    return material_columns(bundle, run_material(bundle, material, allow_outside))
