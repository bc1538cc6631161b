"""Named fabrics: real cloths' measured values (docs/materials.md has the sources and the reduction).

Ten fabrics measured by Wang, Ramamoorthi and O'Brien, "Data-Driven Elastic Models for Cloth:
Modeling and Measurement" (ACM Transactions on Graphics 30(4), SIGGRAPH 2011), from their
published parameter files (areal density; stretching stiffness sampled at six strains, warp, weft,
their coupling and shear; bending stiffness at five curvatures in three directions), reduced to
an isotropic cloth: ``stretch`` the median over the strain samples of the geometric mean of warp
and weft stiffness, ``shear`` the median of the shear term over 4 (their energy counts the Green
strain's off-diagonal, half the shear angle), ``bend`` the median of the three directions' lowest
curvature sample over 4 (ARCSim's hinge, for which they were fitted, stores a quarter of the energy
this package's does for the same value: docs/materials.md; so reduced, their denim's 1.8e-5 N m
lies among Kawabata measurements of denim, 1.4-2.2e-5 N m). Damping was not measured: every fabric
keeps the project's loss time.

``default`` is the cloth every dataset was simulated with before materials existed, in the same
units (the solver's values on the 1,046-vertex dress; docs/materials.md).
"""

from __future__ import annotations

from ..errors import InputError
from .material import Material

WANG_2011 = "Wang, Ramamoorthi and O'Brien 2011 (ACM TOG 30(4))"


# name: (density kg/m^2, stretch N/m, shear N/m, bend N m, what it is; Wang et al.'s name for it)
_MEASURED = {
    "denim": (0.324, 488.0, 17.4, 1.84e-5, "11 oz denim, jeans, 99 % cotton; 11oz-black-denim"),
    "cotton-twill": (0.220, 2127.0, 10.1, 3.13e-5, "trouser twill, 65 % cotton 35 % polyester; royal-target"),
    "jersey": (0.187, 162.0, 6.9, 5.80e-6, "t-shirt interlock, 60 % cotton 40 % polyester; gray-interlock"),
    "rib-knit": (0.276, 93.0, 2.1, 8.05e-6, "underwear rib knit, 95 % cotton 5 % spandex; ivory-rib-knit"),
    "polyester": (0.113, 165.0, 2.3, 5.08e-6, "light jacket polyester; tango-red-jet-set"),
    "polyester-plain": (0.128, 2124.0, 7.8, 1.02e-5, "plain-woven polyester tablecloth; white-dots-on-blk"),
    "ponte": (0.284, 141.0, 7.5, 9.08e-6, "ponte roma knit, 60 % polyester 40 % rayon; camel-ponte-roma"),
    "sweatshirt": (0.224, 95.0, 3.0, 1.14e-5, "sweater knit, 96 % polyester 4 % spandex; navy-sparkle-sweat"),
    "swimwear": (0.204, 73.0, 5.6, 1.47e-5, "swimsuit knit, 87 % nylon 13 % spandex; white-swim-solid"),
    "fleece": (0.228, 190.0, 7.6, 2.19e-5, "blanket, 100 % polyester; pink-ribbon-brown"),
}
FABRICS: dict[str, Material] = {
    "default": Material("default"),
    **{
        name: Material(name=name, density=density, stretch=stretch, shear=shear, bend=bend)
        for name, (density, stretch, shear, bend, _) in _MEASURED.items()
    },
}
ABOUT: dict[str, str] = {
    "default": "the project's cloth before materials (its solver values in physical units)",
    **{name: f"{row[-1]} ({WANG_2011})" for name, row in _MEASURED.items()},
}


def fabric(name: str, where: str = "--material") -> Material:
    """The named fabric; an error naming the known ones otherwise."""
    key = name.strip().lower()
    if key not in FABRICS:
        raise InputError(where, f"unknown fabric {name!r}; known: {', '.join(FABRICS)}")
    return FABRICS[key]
