"""Surface materials: how much of a LiDAR pulse a surface sends back toward the sensor.

A material is described by its *apparent reflectivity* in the monostatic geometry of a LiDAR
(emitter and receiver side by side), as a function of the incidence angle θ between the ray
and the surface normal:

.. math::

    \\rho_\\mathrm{eff}(\\theta) = \\rho_d \\cos\\theta
      + \\frac{F\\, e^{-\\tan^2\\theta / m^2}}{4 m^2 \\cos^5\\theta}
      + \\rho_r \\max(0,\\ 1 - \\theta / \\theta_a)

* ``ρ_d cos θ``: a Lambertian (diffuse) surface of reflectivity ρ_d, the quantity LiDAR
  datasheets quote ("range at 10 % reflectivity");
* the second term: a specular lobe (Beckmann microfacet distribution, RMS facet slope
  ``m = tan(specular_slope_deg)``, Fresnel reflectance ``F``) seen back along the ray, for
  mirror-like surfaces such as solar-cell cover glass, optical solar reflectors and the
  crinkled aluminised film of MLI blankets. At normal incidence it adds ``F / (4 m²)``, far
  above 1 for a smooth surface: a glint;
* the third: a retro-reflector (corner-cube array) returning ρ_r at normal incidence, falling
  linearly to zero at its acceptance half-angle θ_a.

ρ_eff is normalised so that a Lambertian target of reflectivity ρ at normal incidence gives
ρ; the received power of a pulse is proportional to ρ_eff / R^n (see
:mod:`lidarsim_core.instrument.linkbudget`). The equations and the sources of every value are in
``docs/realism.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from .. import kernels
from ..base.errors import ConfigError
from ..base.validation import validate_model


class Material(BaseModel):
    """A surface's reflectance at the sensor's wavelength (see the module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    diffuse_reflectivity: float = Field(
        0.0, ge=0, le=1, description="Lambertian reflectivity ρ_d, 0-1 (the datasheets' "
                                     "'reflectivity' of a range-at-reflectivity figure).")
    specular_reflectance: float = Field(
        0.0, ge=0, le=1, description="Fresnel reflectance F of the mirror-like part, 0-1 "
                                     "(0: no specular lobe).")
    specular_slope_deg: float = Field(
        5.0, gt=0, lt=60, description="RMS facet tilt of the specular lobe (deg): m = tan of "
                                      "it; small for glass, larger for crinkled MLI.")
    retro_reflectivity: float = Field(
        0.0, ge=0, le=1e9, description="Apparent reflectivity of a retro-reflector at normal "
                                       "incidence (may be far above 1, up to 1e9, beyond any "
                                       "cube-corner array's gain: a larger value would make "
                                       "float32 intensities overflow; 0: none).")
    retro_acceptance_deg: float = Field(
        30.0, gt=0, le=90, description="Incidence half-angle (deg) at which the "
                                       "retro-reflector's return has fallen to zero.")
    description: str = Field("", description="What the material is.")
    source: str = Field("", description="Where the values come from ('estimate: ...' if "
                                        "they are estimates).")

    def effective_reflectivity(self, cos_incidence: np.ndarray | float) -> np.ndarray:
        """ρ_eff(θ) for cosines of the incidence angle (see the module docstring)."""
        return MaterialTable.from_materials([self]).effective(
            np.zeros(np.shape(cos_incidence), dtype=np.int64), np.asarray(cos_incidence))


def _lambertian(rho: float, what: str) -> Material:
    return Material(diffuse_reflectivity=rho, description=what,
                    source="definition: an ideal Lambertian reflector")


#: Built-in materials by name. Values for real spacecraft surfaces at near-infrared LiDAR
#: wavelengths (850-1550 nm) are estimates: no measured monostatic BRDF of Envisat's surfaces
#: is public. Each entry says how its values were chosen.
MATERIAL_LIBRARY: dict[str, Material] = {
    "default": Material(
        diffuse_reflectivity=0.5, description="neutral grey Lambertian surface, used for "
        "parts without a material", source="convention of this simulator"),
    "lambertian_10": _lambertian(0.10, "10 % Lambertian reference target"),
    "lambertian_20": _lambertian(0.20, "20 % Lambertian reference target"),
    "lambertian_50": _lambertian(0.50, "50 % Lambertian reference target"),
    "lambertian_80": _lambertian(0.80, "80 % Lambertian reference target"),
    "mli_aluminised_kapton": Material(
        diffuse_reflectivity=0.10, specular_reflectance=0.70, specular_slope_deg=12.0,
        description="MLI blanket, outer layer aluminised polyimide (Kapton) with the polyimide "
                    "outside: the gold/amber blankets of Envisat's bus and instruments",
        source="estimate: polyimide film is nearly transparent above ~600 nm, so in the near "
               "infrared the aluminium backing (reflectance ~0.86 at 900 nm) is seen through "
               "the film (F ≈ 0.7 after two passes and surface losses); crinkling gives a "
               "broad lobe (rms facet tilt ~10-15°) and a weak diffuse part"),
    "solar_cell_glass": Material(
        diffuse_reflectivity=0.07, specular_reflectance=0.03, specular_slope_deg=1.0,
        description="silicon solar cells under cover glass (front of the solar array)",
        source="estimate: cells are designed to absorb the near infrared (a few % diffuse "
               "reflectance with anti-reflection coating); the cover glass reflects ~3-4 % "
               "specularly (Fresnel, n ≈ 1.5 at normal incidence), flat to ~1°"),
    "white_paint": Material(
        diffuse_reflectivity=0.80, description="white thermal-control paint (dishes, "
                                               "radiator areas)",
        source="estimate: white silicone/polyurethane thermal paints are highly diffuse "
               "reflectors in the near infrared (0.8-0.9)"),
    "black_paint": Material(
        diffuse_reflectivity=0.05, description="black thermal-control paint or black "
                                               "polyimide film",
        source="estimate: black paints absorb > 90 % in the near infrared"),
    "osr_mirror": Material(
        diffuse_reflectivity=0.02, specular_reflectance=0.85, specular_slope_deg=2.0,
        description="optical solar reflectors (silvered quartz tiles) on radiators",
        source="estimate: second-surface silver mirrors reflect ~0.9 in the near infrared; "
               "tile mosaics are flat to a few degrees"),
    "anodised_aluminium": Material(
        diffuse_reflectivity=0.35, specular_reflectance=0.30, specular_slope_deg=8.0,
        description="machined or anodised aluminium alloy (launch adapter ring)",
        source="estimate: mixed diffuse and glossy reflection of a machined alloy"),
    "cfrp": Material(
        diffuse_reflectivity=0.08, specular_reflectance=0.05, specular_slope_deg=10.0,
        description="carbon-fibre composite (booms, struts)",
        source="estimate: dark composite, weak sheen"),
    "dark_antenna_film": Material(
        diffuse_reflectivity=0.10, specular_reflectance=0.05, specular_slope_deg=10.0,
        description="dark thermal film over a radar antenna's radiating face",
        source="estimate: dark (germanium- or carbon-loaded) polyimide film"),
    "retroreflector": Material(
        diffuse_reflectivity=0.10, retro_reflectivity=1000.0, retro_acceptance_deg=30.0,
        description="corner-cube retro-reflector array (docking and ranging aid)",
        source="estimate: corner cubes return a beam 10²-10⁴ times brighter than a white "
               "Lambertian surface of the same area; acceptance ~±30°"),
}


def material_from_colour(rgb: np.ndarray) -> dict[str, Any]:
    """A material mapping from a visible colour: diffuse reflectivity = mean linear RGB.

    Mesh files carry colours, not infrared reflectances; the visible albedo is a proxy that a
    scenario can override part by part.

    Parameters
    ----------
    rgb
        sRGB colour, three values in 0-1.
    """
    srgb = np.clip(np.asarray(rgb, dtype=np.float64)[:3], 0.0, 1.0)
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    return {"diffuse_reflectivity": round(float(linear.mean()), 6),
            "description": "from the mesh file's material colour",
            "source": "mesh file colour (visible albedo as a proxy)"}


@dataclass(frozen=True)
class MaterialTable:
    """Materials of every scene-wide part, as arrays indexed by part (vectorised ρ_eff)."""

    materials: tuple[Material, ...]
    diffuse: np.ndarray
    specular: np.ndarray
    slope2: np.ndarray
    retro: np.ndarray
    acceptance: np.ndarray

    @classmethod
    def from_materials(cls, materials: list[Material]) -> "MaterialTable":
        """The table of ``materials`` (index = part)."""
        def column(attr: str) -> np.ndarray:
            return np.array([getattr(m, attr) for m in materials], dtype=np.float64)

        slope = np.tan(np.radians(column("specular_slope_deg")))
        return cls(tuple(materials), column("diffuse_reflectivity"),
                   column("specular_reflectance"), slope * slope, column("retro_reflectivity"),
                   np.radians(column("retro_acceptance_deg")))

    def effective(self, part: np.ndarray, cos_incidence: np.ndarray) -> np.ndarray:
        """ρ_eff for hits on ``part`` (scene-wide indices) at incidence cosines
        ``cos_incidence`` (|cos|, 0-1)."""
        part = np.asarray(part)
        cos_incidence = np.asarray(cos_incidence, dtype=np.float64)
        if part.ndim != 1 or cos_incidence.shape != part.shape:
            # a scalar or a grid: computed flat (element by element, the same bits), returned
            # in its shape
            shape = np.broadcast_shapes(part.shape, cos_incidence.shape)
            flat = self.effective(np.broadcast_to(part, shape).ravel(),
                                  np.broadcast_to(cos_incidence, shape).ravel())
            return flat.reshape(shape)
        if kernels.enabled():  # the same bits in two compiled passes (kernels.reflectance)
            return self._effective_compiled(part, cos_incidence)
        # per hit: the tables' rows gathered once, the arithmetic on the lit hits in place
        # (each operation is the same IEEE operation on the same values as written out in
        # the formula, so the bits do not depend on it; NumPy's exp and arccos keep their
        # inputs' layout)
        c = np.clip(cos_incidence, 0.0, 1.0)
        out = np.take(self.diffuse, part)
        out *= c
        if self.specular.any():
            lit = np.take(self.specular > 0, part)
            lit &= c > 0
            if lit.any():
                lit_part = part[lit]
                cl = c[lit]
                c2 = cl * cl
                m2 = np.take(self.slope2, lit_part)
                tan2 = np.subtract(1.0, c2)
                tan2 /= c2
                np.negative(tan2, out=tan2)  # -tan2 / m2: the sign flip is exact
                tan2 /= m2
                lobe = np.exp(tan2)
                denominator = 4.0 * m2
                denominator *= c2
                denominator *= c2
                denominator *= cl
                lobe /= denominator
                lobe *= np.take(self.specular, lit_part)
                out[lit] += lobe
        if self.retro.any():
            gain = self.retro[part]
            on = gain > 0
            if on.any():
                theta = np.arccos(c[on])
                out[on] += gain[on] * np.maximum(0.0, 1.0 - theta / self.acceptance[part][on])
        return out

    def _effective_compiled(self, part: np.ndarray, cos_incidence: np.ndarray) -> np.ndarray:
        """:meth:`effective` through :mod:`lidarsim_core.kernels.reflectance`: the gathers
        and the arithmetic compiled, ``exp`` and ``arccos`` NumPy's."""
        from ..kernels.reflectance import reflectance_sum, reflectance_terms

        part = np.ascontiguousarray(part)
        if part.dtype.kind not in "iu":
            part = part.astype(np.int64)
        out, c, lit, exponent, on, c_on = reflectance_terms(
            part, np.ascontiguousarray(cos_incidence, dtype=np.float64), self.diffuse,
            self.specular, self.slope2, self.retro)
        if len(lit) or len(on):
            reflectance_sum(out, c, part, lit, np.exp(exponent), self.slope2, self.specular,
                            on, np.arccos(c_on), self.retro, self.acceptance)
        return out


def resolve_material(spec: str | Mapping[str, Any], library: Mapping[str, Material], *,
                     source: str, field: str) -> Material:
    """A material from a library name or an inline mapping of :class:`Material` fields.

    Raises
    ------
    ConfigError
        Naming ``field`` when the name is unknown or a value is invalid.
    """
    if isinstance(spec, str):
        if spec not in library:
            raise ConfigError(f"unknown material '{spec}'; known: {', '.join(sorted(library))}",
                              source=source, field=field)
        return library[spec]
    return validate_model(Material, dict(spec), source=source, prefix=field)


def material_library(custom: Mapping[str, Mapping[str, Any]], *, source: str
                     ) -> dict[str, Material]:
    """The built-in library plus a scenario's own named materials (``materials:``)."""
    library = dict(MATERIAL_LIBRARY)
    for name, spec in custom.items():
        if name in MATERIAL_LIBRARY:
            raise ConfigError(f"'{name}' is a built-in material; give yours another name",
                              source=source, field=f"materials.{name}")
        library[name] = resolve_material(spec, library, source=source,
                                         field=f"materials.{name}")
    return library


def part_materials(part_names: tuple[str, ...], defaults: tuple[Any, ...],
                   assigned: Mapping[str, Any], library: Mapping[str, Material], *,
                   source: str, field: str) -> list[Material]:
    """One material per part of a mesh.

    Precedence: the scenario's entry for the part, then its ``"*"`` entry, then the mesh's
    own default (procedural model or mesh-file colour), then ``default``.

    Raises
    ------
    ConfigError
        When ``assigned`` names a part the mesh does not have.
    """
    unknown = sorted(set(assigned) - set(part_names) - {"*"})
    if unknown:
        raise ConfigError(f"no part named {unknown[0]!r}; the mesh's parts are: "
                          f"{', '.join(part_names)}", source=source, field=f"{field}.{unknown[0]}")
    out = []
    for i, part in enumerate(part_names):
        key = part if part in assigned else "*" if "*" in assigned else None
        if key is not None:
            out.append(resolve_material(assigned[key], library, source=source,
                                        field=f"{field}.{key}"))
            continue
        default = defaults[i] if i < len(defaults) else None
        out.append(library["default"] if default is None else
                   resolve_material(default, library, source=source,
                                    field=f"{field} (mesh default of part '{part}')"))
    return out


def specular_peak(material: Material) -> float:
    """The specular lobe's apparent reflectivity at normal incidence, F / (4 m²)."""
    m = math.tan(math.radians(material.specular_slope_deg))
    return material.specular_reflectance / (4.0 * m * m)
