"""Built-in plugin: procedural targets (the Envisat model and analytic test shapes)."""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import Field, field_validator

from ..base.components import ComponentOptions
from ..hookspecs import hookimpl
from ..scene.mesh import Mesh, merge_parts
from ..scene.targets import TargetModel


#: Largest integer ``detail`` of the Envisat model (its
#: ``lidarsim_core.models.envisat.MAX_TESSELLATION_FACTOR``, kept here so the options are
#: validated without importing the builder and trimesh).
ENVISAT_MAX_DETAIL = 32


class EnvisatOptions(ComponentOptions):
    """Options of the Envisat model."""

    detail: Literal["coarse", "medium", "fine"] | int = Field(
        "medium", description="'coarse' (hundreds of triangles), 'medium' (thousands), 'fine' "
                              "(~100k), or an integer tessellation factor.")

    @field_validator("detail", mode="before")
    @classmethod
    def _detail_in_range(cls, value: Any) -> Any:
        if isinstance(value, bool) or (isinstance(value, (int, float)) and
                                       not 0 <= value <= ENVISAT_MAX_DETAIL):
            raise ValueError(f"detail must be 'coarse', 'medium', 'fine' or an integer "
                             f"0..{ENVISAT_MAX_DETAIL}, got {value!r}")
        return value


#: Default material of every Envisat part (names of :data:`lidarsim_core.scene.materials.MATERIAL_LIBRARY`
#: entries, whose sources say how their values were estimated). The assignment follows
#: Envisat's appearance in ESA imagery: gold/amber MLI blankets over the bus and instruments,
#: silicon cells on the array front, a dark film on the ASAR face, white dishes; the radiators'
#: finish (OSR tiles) and the boom's (composite) are our assumptions.
ENVISAT_MATERIALS: dict[str, str] = {
    "bus": "mli_aluminised_kapton",
    "solar_array": "solar_cell_glass",
    "solar_array_boom": "cfrp",
    "asar_antenna": "dark_antenna_film",
    "ka_antenna": "white_paint",
    "ka_mast": "mli_aluminised_kapton",
    "adapter_ring": "anodised_aluminium",
    "meris": "mli_aluminised_kapton",
    "aatsr": "mli_aluminised_kapton",
    "ra2_antenna": "white_paint",
    "radiators": "osr_mirror",
}


class EnvisatModel(TargetModel):
    """Parametric ESA Envisat: bus, solar array on its boom, ASAR antenna and appendages."""

    name = "envisat"
    Options = EnvisatOptions
    options: EnvisatOptions

    def build(self) -> Mesh:
        from .envisat import build_envisat

        vertices, faces, face_part, names = build_envisat(self.options.detail)
        return Mesh.from_arrays(vertices, faces, face_part, names, name="envisat",
                                part_materials=tuple(ENVISAT_MATERIALS[n] for n in names))


class BoxOptions(ComponentOptions):
    """Options of the box model."""

    extents_m: tuple[float, float, float] = Field((1.0, 1.0, 1.0), description="Edge lengths (m).")


class BoxModel(TargetModel):
    """Axis-aligned box centred on the body origin (analytic test target)."""

    name = "box"
    Options = BoxOptions
    options: BoxOptions

    def build(self) -> Mesh:
        import trimesh

        box = trimesh.creation.box(extents=self.options.extents_m)
        return merge_parts([("box", box.vertices, box.faces)], name="box")


class SphereOptions(ComponentOptions):
    """Options of the sphere model."""

    radius_m: float = Field(1.0, gt=0)
    subdivisions: int = Field(4, ge=0, le=7, description="Icosphere subdivision level.")


class SphereModel(TargetModel):
    """Icosphere centred on the body origin (analytic test target)."""

    name = "sphere"
    Options = SphereOptions
    options: SphereOptions

    def build(self) -> Mesh:
        import trimesh

        sphere = trimesh.creation.icosphere(self.options.subdivisions, self.options.radius_m)
        return merge_parts([("sphere", sphere.vertices, sphere.faces)], name="sphere")


class PlateOptions(ComponentOptions):
    """Options of the plate model."""

    size_m: tuple[float, float] = Field((1.0, 1.0), description="Edge lengths along Y and Z (m).")


class PlateModel(TargetModel):
    """Flat square plate in the body YZ plane facing -X and +X (two triangles)."""

    name = "plate"
    Options = PlateOptions
    options: PlateOptions

    def build(self) -> Mesh:
        hy, hz = np.asarray(self.options.size_m) / 2
        vertices = np.array([[0, -hy, -hz], [0, hy, -hz], [0, hy, hz], [0, -hy, hz]], float)
        faces = np.array([[0, 1, 2], [0, 2, 3]])
        return merge_parts([("plate", vertices, faces)], name="plate")


@hookimpl
def lidarsim_register_target_models(register: Any) -> None:
    """Register Envisat and the analytic shapes."""
    for model in (EnvisatModel, BoxModel, SphereModel, PlateModel):
        register(model)
