"""A cloth's material in physical units (:class:`Material`), the named fabrics (:mod:`.fabrics`) and
how a user names one: ``silk``, ``silk,bend=4e-6``, ``density=0.2,stretch=5000`` or a YAML file.

The simulator maps a material to its own parameters in one place
(:mod:`hrr_garment.sim.cloth_parameters`); this module only holds and checks the physical values.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

from ..errors import InputError

# what each value means, in the units it is given in (docs/materials.md)
UNITS = {
    "density": "kg/m^2",
    "stretch": "N/m",
    "shear": "N/m",
    "bend": "N m",
    "damping": "s",
}
# the range a material may take (each value): the solver is measured to hold the named fabrics, and a
# value outside the fabrics' span by far more than a factor of a few is a typo, not a cloth
LIMITS = {
    "density": (0.01, 2.0),
    "stretch": (20.0, 2.0e5),
    "shear": (1.0, 2.0e5),
    "bend": (1.0e-7, 1.0e-3),
    "damping": (0.0, 1.0),
}


@dataclass(frozen=True)
class Material:
    """One cloth, in physical units (small-strain values, the cloth taken as isotropic)."""

    name: str = "custom"
    density: float = 0.15  # areal density, kg per square metre (fabric weight: 150 g/m^2)
    stretch: float = 26_667.0  # tensile stiffness per unit width (2D Young's modulus), N/m
    shear: float = 10_000.0  # in-plane shear stiffness (2D shear modulus), N/m per radian
    bend: float = 3.2e-5  # bending rigidity (moment per width per curvature, KES B), N m
    damping: float = 0.1  # loss time of bending (viscous moment / elastic moment rate), s

    def __post_init__(self) -> None:
        for key, (low, high) in LIMITS.items():
            value = getattr(self, key)
            ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
            if not ok or not low <= value <= high:
                raise InputError(
                    f"material {self.name!r}",
                    f"{key} {value!r} {UNITS[key]} is outside the range a cloth here may take "
                    f"({low:g}-{high:g} {UNITS[key]})",
                )

    def to_dict(self) -> dict:
        return asdict(self)

    def describe(self) -> str:
        """One line: the name and the values with their units."""
        values = ", ".join(f"{k} {getattr(self, k):.4g} {UNITS[k]}" for k in UNITS)
        return f"{self.name} ({values})"


VALUE_NAMES = tuple(f.name for f in fields(Material) if f.name != "name")


def _number(text: str, key: str, where: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(where, f"{key}={text!r} is not a number") from None


def _with_values(base: Material, values: dict, where: str, name: str | None = None) -> Material:
    unknown = sorted(set(values) - set(VALUE_NAMES))
    if unknown:
        raise InputError(
            where, f"unknown material value(s) {', '.join(unknown)}; a material has {', '.join(VALUE_NAMES)}"
        )
    changed = {k: v for k, v in values.items() if v != getattr(base, k)}
    label = name or (base.name if not changed else f"{base.name}+" + ",".join(sorted(changed)))
    try:
        return replace(base, name=label, **values)
    except InputError as exc:
        raise InputError(where, exc.problem) from None


def material_file(spec: str) -> Path | None:
    """The YAML file ``spec`` names, or None when it names a fabric or values."""
    text = spec.strip()
    return Path(text) if text.endswith((".yaml", ".yml")) else None


def parse_material(spec: str, where: str = "--material") -> Material:
    """A material from what a user typed: a fabric's name (``silk``), a name with values changed
    (``silk,bend=4e-6``), values alone over the default cloth (``density=0.2,stretch=5000``), or a
    YAML file of values (``name:`` optional). Errors name ``where`` and the problem."""
    from .fabrics import FABRICS, fabric

    path = material_file(spec)
    if path is not None:
        return read_material(path)
    base = Material(name="default")
    values: dict[str, float] = {}
    for i, part in enumerate(p.strip() for p in spec.strip().split(",")):
        if "=" in part:
            key, _, number = part.partition("=")
            values[key.strip()] = _number(number.strip(), key.strip(), where)
        elif i == 0 and part:
            base = fabric(part, where)
        else:
            raise InputError(
                where,
                f"{part!r} is neither a fabric ({', '.join(FABRICS)}) first nor a value like bend=4e-6",
            )
    return _with_values(base, values, where)


def material_from(value: object, where: str = "material") -> Material:
    """A :class:`Material` from a settings value: one already made, a string as
    :func:`parse_material` reads it, or a mapping of values (``name`` and ``base``, a fabric, optional)."""
    if isinstance(value, Material):
        return value
    if isinstance(value, str):
        return parse_material(value, where)
    if isinstance(value, dict):
        from .fabrics import fabric

        values = dict(value)
        name = values.pop("name", None)
        base = fabric(str(values.pop("base")), where) if "base" in values else Material(name="default")
        for key, number in values.items():
            if isinstance(number, bool) or not isinstance(number, (int, float)):
                raise InputError(where, f"{key}: {number!r} is not a number")
        return _with_values(base, values, where, None if name is None else str(name))
    raise InputError(
        where, f"a material is a fabric's name or a mapping of values, not {type(value).__name__}"
    )


def read_material(path: Path) -> Material:
    """A material from a YAML file of values (see :func:`material_from`)."""
    import yaml

    from ..input_files import read_input_text

    try:
        values = yaml.safe_load(read_input_text(path, what="a material file"))
    except yaml.YAMLError as exc:
        raise InputError(path, f"is not valid YAML ({exc.__class__.__name__})") from None
    if not isinstance(values, dict):
        raise InputError(path, "a material file is a mapping of values (density: 0.2, ...)")
    values.setdefault("name", path.stem)
    return material_from(values, str(path))


def recorded_material(text: str | None, where: str) -> Material | None:
    """The cloth a file records as JSON (out.h5's ``material`` attribute: a material's values and
    name, :meth:`Material.to_dict`), or None where it records none."""
    import json

    if text is None:
        return None
    try:
        values = json.loads(text)
    except (TypeError, ValueError):
        raise InputError(where, f"its material {text!r} is not a JSON object of values") from None
    return material_from(values, where)
