"""Parametric triangle-mesh model of ESA's Envisat, built in code.

The demo target of the simulator is Envisat, the 8-tonne derelict that is the
reference object for active-debris-removal studies. This module assembles an
approximate model of it from ``trimesh.creation`` primitives and gridded boxes,
so no mesh file has to be shipped or downloaded. Every part is a closed,
outward-oriented solid with its own label, so a ray caster can report which
part a LiDAR return came from (for example the launch adapter ring, the usual
capture target).

The model is an *approximation*: all dimensions below are rounded public
figures or plausible guesses chosen to reproduce the published envelope, not
values taken from ESA drawings. Published figures used:

* in-orbit envelope 26 m x 10 m x 5 m; launch configuration 10.5 m long inside a
  4.57 m fairing envelope (ESA Envisat "space segment" page);
* solar array about 14 m x 5 m, deployed on a boom from the service module;
* ASAR antenna about 10 m x 1.3 m;
* RA-2 radar-altimeter dish about 1.2 m diameter, Earth pointing;
* the service module carries the launcher interface at one end.

Body frame
----------
Right-handed, metres, origin at the geometric centre of the main bus box.

* ``+X`` along the bus long axis, toward the service-module end, which carries
  the solar-array boom and the launch adapter ring. The payload-module end is
  ``-X``.
* ``+Z`` toward nadir: the Earth-facing face carrying MERIS, AATSR and the RA-2
  dish. The Ka-band antenna mast stands on the zenith face (``-Z``).
* ``+Y = Z x X`` completes the frame. The solar array is displaced toward
  ``+Y``; the side-looking ASAR antenna is on the ``-Y`` face.

The axis directions follow ESA's satellite frame (Xs along the long axis,
Zs Earth pointing), but the origin and the sign of X are this model's own.

Where the parts are (nominal values, metres)
--------------------------------------------
==================== ==========================================================
part                 placement
==================== ==========================================================
``bus``              box X [-5, 5], Y [-1.5, 1.5], Z [-1.7, 1.7]
``solar_array``      panel X [7, 21], Y [3.3, 8.3], Z [-0.03, 0.03]
``solar_array_boom`` strut from the +X face at (4.95, 1.1, 0) to a yoke along
                     the array's root edge at X = 6.95
``asar_antenna``     slab X [-5, 5], Y [-1.705, -1.505], Z [-0.65, 0.65]
``ka_antenna``       0.9 m dish at (-3.5, 0.6), rim near Z = -2.65, facing -Z
``ka_mast``          post from the zenith face to Z = -2.5 at (-3.5, 0.6)
``adapter_ring``     ring, outer diameter 1.2 m, on the +X face, X [4.99, 5.4],
                     with a flange at its outer end
``meris``            box X [-4.6, -3.0], Y [-0.3, 1.1], Z [1.705, 2.255]
``aatsr``            box X [-2.6, -1.3], Y [-1.2, -0.1], Z [1.705, 2.305]
``ra2_antenna``      1.2 m dish on a pedestal at (0.6, 0.2), facing +Z
``radiators``        two thin panels on the +Y face, one on the zenith face
==================== ==========================================================

The resulting bounding box is X [-5, 21], Y [-1.705, 8.3], Z [-2.65, 2.305],
that is 26.0 m x 10.0 m x 4.95 m.

Panels and boxes stand off the bus by :data:`MOUNT_GAP_M` instead of touching
it, so no two parts have coincident coplanar faces, which would make a ray
caster's choice of hit (and so the part label) arbitrary. Posts and rings are
sunk a few centimetres into the surface they stand on; their embedded caps are
hidden inside the other solid and are never hit from outside.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass

import numpy as np
import trimesh

__all__ = [
    "DETAIL_LEVELS",
    "ENVISAT_PARTS",
    "MAX_TESSELLATION_FACTOR",
    "EnvisatTessellation",
    "build_envisat",
    "resolve_detail",
]

# Part names in a fixed order; ``face_part`` indexes into this tuple.
ENVISAT_PARTS: tuple[str, ...] = (
    "bus",
    "solar_array",
    "solar_array_boom",
    "asar_antenna",
    "ka_antenna",
    "ka_mast",
    "adapter_ring",
    "meris",
    "aatsr",
    "ra2_antenna",
    "radiators",
)

# ---------------------------------------------------------------------------
# Dimensions. All are approximations (see the module docstring): rounded public
# figures where they exist, otherwise values picked so the assembled model
# matches the published 26 m x 10 m x 5 m in-orbit envelope.
# ---------------------------------------------------------------------------

# Small standoff between a mounted panel or box and the bus face it sits on.
# Big enough that float32 ray casting never confuses the two surfaces, small
# enough to be invisible to a LiDAR except at grazing incidence.
MOUNT_GAP_M = 0.005

# Main bus (service module plus payload module as one box). Length is the
# published ~10 m; a 3.0 m x 3.4 m section fits the 4.57 m launch envelope
# (diagonal 4.53 m).
BUS_LENGTH_M = 10.0
BUS_WIDTH_M = 3.0
BUS_HEIGHT_M = 3.4

# Solar array: published ~14 m x 5 m. Thickness is a guess for a rigid-panel
# wing. It is held 2 m beyond the bus's +X end so the X span is 10 + 2 + 14 =
# 26 m, and displaced sideways so the Y span with the ASAR is ~10 m.
SOLAR_ARRAY_LENGTH_M = 14.0
SOLAR_ARRAY_WIDTH_M = 5.0
SOLAR_ARRAY_THICKNESS_M = 0.06
SOLAR_ARRAY_ROOT_X_M = 7.0
SOLAR_ARRAY_INNER_Y_M = 3.3
SOLAR_ARRAY_CENTRE_Z_M = 0.0

# Boom: a single strut from the bus +X face to a yoke along the array's root
# edge. The yoke overlaps the panel edge by 1 cm so the wing is visibly
# attached; both radii are guesses.
BOOM_RADIUS_M = 0.10
BOOM_ROOT_Y_M = 1.1
# Struts and posts are sunk this far into the face they stand on, hiding
# their end caps inside the bus.
POST_EMBED_M = 0.05
YOKE_RADIUS_M = 0.06
YOKE_END_MARGIN_M = 0.1
YOKE_OVERLAP_M = 0.01

# ASAR antenna: published ~10 m x 1.3 m; thickness is a guess. Mounted on the
# -Y face, its long side along the bus.
ASAR_LENGTH_M = 10.0
ASAR_HEIGHT_M = 1.3
ASAR_THICKNESS_M = 0.2

# Ka-band data-relay antenna (link to Artemis): dish size and mast height are
# guesses; the mast is sized so the model's Z span is ~5 m.
KA_POSITION_XY_M = (-3.5, 0.6)
KA_MAST_RADIUS_M = 0.06
KA_MAST_TOP_ABOVE_FACE_M = 0.8
KA_DISH_DIAMETER_M = 0.9
KA_DISH_FOCAL_LENGTH_M = 0.36

# RA-2 radar altimeter: published ~1.2 m dish, pointing at nadir; f/D and the
# pedestal are guesses.
RA2_POSITION_XY_M = (0.6, 0.2)
RA2_PEDESTAL_RADIUS_M = 0.15
RA2_PEDESTAL_TOP_ABOVE_FACE_M = 0.25
RA2_DISH_DIAMETER_M = 1.2
RA2_DISH_FOCAL_LENGTH_M = 0.48

# Reflector shell thickness for both dishes, so each is a closed solid.
DISH_SHELL_THICKNESS_M = 0.02

# Launch adapter ring on the service-module end: ~1.2 m outer diameter
# cylinder, the usual capture interface in debris-removal studies. Wall,
# length and flange sizes are guesses.
ADAPTER_RING_OUTER_RADIUS_M = 0.6
ADAPTER_RING_WALL_M = 0.05
ADAPTER_RING_LENGTH_M = 0.4
ADAPTER_RING_EMBED_M = 0.01
ADAPTER_FLANGE_RADII_M = (0.56, 0.66)
ADAPTER_FLANGE_LENGTH_M = 0.06
# Pull the flange back from the ring's end face so the two annular end faces
# are not coplanar.
ADAPTER_FLANGE_SETBACK_M = 0.005

# Instrument boxes on the nadir face, given as (x_min, x_max, y_min, y_max,
# height): rough envelopes, not instrument drawings.
MERIS_BOX_M = (-4.6, -3.0, -0.3, 1.1, 0.55)
AATSR_BOX_M = (-2.6, -1.3, -1.2, -0.1, 0.6)

# Radiator panels (thin plates off the bus faces); sizes are guesses.
RADIATOR_THICKNESS_M = 0.03
# On the +Y face: (x_min, x_max, z_min, z_max) for each panel.
RADIATORS_PLUS_Y_M = ((0.8, 4.6, -1.4, 1.4), (-4.6, -0.8, -1.4, 1.4))
# On the zenith (-Z) face: (x_min, x_max, y_min, y_max).
RADIATORS_ZENITH_M = ((0.5, 4.5, -1.2, 1.2),)

# ---------------------------------------------------------------------------
# Tessellation.
# ---------------------------------------------------------------------------

# At tessellation factor k >= 1, flat faces are split into grid cells no
# larger than this divided by k.
PANEL_CELL_AT_FACTOR_ONE_M = 1.0
# Cylinders and dishes get max(MIN_SECTIONS, SECTIONS_PER_FACTOR * k) sections.
MIN_SECTIONS = 12
SECTIONS_PER_FACTOR = 8
# Dish profiles get max(MIN_DISH_RINGS, DISH_RINGS_PER_FACTOR * k) rings.
MIN_DISH_RINGS = 2
DISH_RINGS_PER_FACTOR = 2
# Largest integer factor accepted. The triangle count grows as ~950 k^2, so
# k = 32 is already ~0.96 million triangles.
MAX_TESSELLATION_FACTOR = 32


@dataclass(frozen=True)
class EnvisatTessellation:
    """Tessellation settings for :func:`build_envisat`.

    Attributes
    ----------
    factor : int
        The integer tessellation factor these settings came from.
    panel_cell_m : float
        Largest grid-cell edge, in metres, used to split the flat faces of
        boxes and panels. ``math.inf`` means no splitting, so each box face is
        two triangles.
    cylinder_sections : int
        Number of facets around cylinders, rings and dishes.
    dish_rings : int
        Number of radial steps along each surface of a dish's profile.
    """

    factor: int
    panel_cell_m: float
    cylinder_sections: int
    dish_rings: int


def _tessellation_from_factor(factor: int) -> EnvisatTessellation:
    """Derive the tessellation settings for an integer factor."""
    return EnvisatTessellation(
        factor=factor,
        panel_cell_m=math.inf if factor == 0 else PANEL_CELL_AT_FACTOR_ONE_M / factor,
        cylinder_sections=max(MIN_SECTIONS, SECTIONS_PER_FACTOR * factor),
        dish_rings=max(MIN_DISH_RINGS, DISH_RINGS_PER_FACTOR * factor),
    )


# Named levels. Triangle counts: coarse 672, medium 9,884, fine 95,804.
DETAIL_LEVELS: dict[str, EnvisatTessellation] = {
    "coarse": _tessellation_from_factor(0),
    "medium": _tessellation_from_factor(3),
    "fine": _tessellation_from_factor(10),
}


def resolve_detail(detail: str | int) -> EnvisatTessellation:
    """Turn a ``detail`` argument into tessellation settings.

    Parameters
    ----------
    detail : str or int
        A key of :data:`DETAIL_LEVELS` (``"coarse"``, ``"medium"``,
        ``"fine"``), or an integer tessellation factor ``k`` in
        ``[0, MAX_TESSELLATION_FACTOR]``. See :func:`build_envisat`.

    Returns
    -------
    EnvisatTessellation
        The settings.

    Raises
    ------
    ValueError
        If ``detail`` is an unknown name or an out-of-range factor.
    TypeError
        If ``detail`` is neither a string nor an integer.
    """
    if isinstance(detail, str):
        try:
            return DETAIL_LEVELS[detail]
        except KeyError:
            raise ValueError(
                f"unknown detail level {detail!r}; expected one of "
                f"{sorted(DETAIL_LEVELS)} or an integer factor"
            ) from None
    # bool is an int subclass, but True/False as a factor is surely a mistake.
    if isinstance(detail, bool):
        raise TypeError("detail must be a level name or an integer factor, not bool")
    try:
        factor = operator.index(detail)
    except TypeError:
        raise TypeError(
            f"detail must be a level name or an integer factor, not {type(detail).__name__}"
        ) from None
    if not 0 <= factor <= MAX_TESSELLATION_FACTOR:
        raise ValueError(
            f"tessellation factor must be in [0, {MAX_TESSELLATION_FACTOR}], got {factor}"
        )
    return _tessellation_from_factor(factor)


# ---------------------------------------------------------------------------
# Primitive builders. Each returns one closed, outward-oriented trimesh body.
# ---------------------------------------------------------------------------


def _divisions(length: float, max_cell: float) -> int:
    """Number of grid cells needed so that no cell exceeds ``max_cell``."""
    if math.isinf(max_cell):
        return 1
    # The small tolerance stops 1.0 / 0.1 = 10.000000000000002 becoming 11.
    return max(1, math.ceil(length / max_cell - 1e-9))


def _grid_box(lower, upper, max_cell: float) -> trimesh.Trimesh:
    """Axis-aligned box whose faces are split into a grid of small triangles.

    Parameters
    ----------
    lower, upper : array_like of float, shape (3,)
        Opposite corners, ``lower < upper`` on every axis.
    max_cell : float
        Largest grid-cell edge; ``math.inf`` gives a plain 12-triangle box.

    Returns
    -------
    trimesh.Trimesh
        Watertight box with outward normals.

    Notes
    -----
    Every face on a given axis samples the same ``linspace`` ticks, so the
    vertices along a shared box edge are bit-identical and an exact
    ``np.unique`` welds the six faces into one watertight mesh. A library
    subdivision of ``trimesh.creation.box`` would split triangles by midpoint
    and leave long slivers on thin panels; a grid keeps cells near-square.
    """
    lower = np.asarray(lower, dtype=np.float64)
    upper = np.asarray(upper, dtype=np.float64)
    ticks = [
        np.linspace(lower[k], upper[k], _divisions(upper[k] - lower[k], max_cell) + 1)
        for k in range(3)
    ]
    vertex_blocks = []
    face_blocks = []
    offset = 0
    for a in range(3):
        # (b, c, a) is a cyclic permutation, so e_b x e_c = +e_a and a cell
        # wound b-then-c faces +a.
        b, c = (a + 1) % 3, (a + 2) % 3
        grid_b, grid_c = np.meshgrid(ticks[b], ticks[c], indexing="ij")
        index = np.arange(grid_b.size).reshape(grid_b.shape)
        v00 = index[:-1, :-1].ravel()
        v10 = index[1:, :-1].ravel()
        v11 = index[1:, 1:].ravel()
        v01 = index[:-1, 1:].ravel()
        toward_plus = np.concatenate(
            [np.column_stack([v00, v10, v11]), np.column_stack([v00, v11, v01])]
        )
        for coordinate, faces in ((lower[a], toward_plus[:, ::-1]), (upper[a], toward_plus)):
            block = np.empty((grid_b.size, 3), dtype=np.float64)
            block[:, a] = coordinate
            block[:, b] = grid_b.ravel()
            block[:, c] = grid_c.ravel()
            vertex_blocks.append(block)
            face_blocks.append(faces + offset)
            offset += grid_b.size
    vertices = np.concatenate(vertex_blocks)
    faces = np.concatenate(face_blocks)
    unique_vertices, inverse = np.unique(vertices, axis=0, return_inverse=True)
    return trimesh.Trimesh(unique_vertices, inverse.reshape(-1)[faces], process=False)


def _rod(start, end, radius: float, sections: int) -> trimesh.Trimesh:
    """Closed cylinder between two points."""
    return trimesh.creation.cylinder(
        radius=radius, segment=np.array([start, end], dtype=np.float64), sections=sections
    )


def _tube(start, end, r_inner: float, r_outer: float, sections: int) -> trimesh.Trimesh:
    """Closed thick-walled tube (annulus) between two points."""
    return trimesh.creation.annulus(
        r_min=r_inner,
        r_max=r_outer,
        segment=np.array([start, end], dtype=np.float64),
        sections=sections,
    )


def _dish_seat_depth(hub_radius: float, focal_length: float) -> float:
    """How far past a dish's apex the top of its supporting post should sit.

    The post's flat top must lie inside the shell: above the back surface at
    the post's radius, ``hub_radius**2 / (4 f)``, and below the front surface
    on the axis, the shell thickness. Halfway between gives the most margin.
    """
    back_at_hub = hub_radius**2 / (4.0 * focal_length)
    if back_at_hub >= DISH_SHELL_THICKNESS_M:
        raise ValueError("post too wide to seat inside the dish shell")
    return 0.5 * (back_at_hub + DISH_SHELL_THICKNESS_M)


def _dish(
    apex,
    facing_plus_z: bool,
    diameter: float,
    focal_length: float,
    hub_radius: float,
    settings: EnvisatTessellation,
) -> trimesh.Trimesh:
    """Paraboloidal reflector as a closed shell of finite thickness.

    Parameters
    ----------
    apex : array_like of float, shape (3,)
        Vertex of the convex (back) surface of the reflector.
    facing_plus_z : bool
        True if the concave side opens toward body ``+Z``, else toward ``-Z``.
    diameter, focal_length : float
        Rim diameter and focal length of the reflecting surface, metres.
    hub_radius : float
        Radius of the post carrying the dish. The profile always has a ring
        at this radius, so the faceted back surface passes exactly through
        the parabola there and the post's top (see :func:`_dish_seat_depth`)
        stays hidden inside the shell even at the coarsest level, where a
        chord from the axis to a far ring would otherwise cut through it.
    settings : EnvisatTessellation
        Supplies the number of sections and of radial rings.

    Returns
    -------
    trimesh.Trimesh
        Watertight shell with outward normals.
    """
    radius = 0.5 * diameter
    r = np.concatenate([[0.0], np.linspace(hub_radius, radius, settings.dish_rings)])
    back = r**2 / (4.0 * focal_length)
    front = back + DISH_SHELL_THICKNESS_M
    # Closed profile in (r, z), both ends on the axis: back surface out to the
    # rim, across the rim, front surface back to the axis. revolve() welds the
    # on-axis points into single poles.
    profile = np.vstack(
        [np.column_stack([r, back]), np.column_stack([r[::-1], front[::-1]])]
    )
    # Exact axis flips rather than a general rotation keep coordinates free of
    # rounding noise.
    sign = 1.0 if facing_plus_z else -1.0
    transform = np.diag([1.0, sign, sign, 1.0])
    transform[:3, 3] = apex
    mesh = trimesh.creation.revolve(
        profile, sections=settings.cylinder_sections, transform=transform
    )
    # revolve() winds faces by the profile's direction; make the shell
    # outward-facing whatever the direction was.
    if mesh.volume < 0.0:
        mesh.invert()
    return mesh


# ---------------------------------------------------------------------------
# Parts.
# ---------------------------------------------------------------------------


def _part_bodies(settings: EnvisatTessellation) -> dict[str, list[trimesh.Trimesh]]:
    """Build every part as a list of closed bodies, keyed by part name."""
    cell = settings.panel_cell_m
    sections = settings.cylinder_sections
    hx, hy, hz = 0.5 * BUS_LENGTH_M, 0.5 * BUS_WIDTH_M, 0.5 * BUS_HEIGHT_M
    gap = MOUNT_GAP_M

    bus = _grid_box((-hx, -hy, -hz), (hx, hy, hz), cell)

    array_y0 = SOLAR_ARRAY_INNER_Y_M
    array_y1 = SOLAR_ARRAY_INNER_Y_M + SOLAR_ARRAY_WIDTH_M
    array_z = SOLAR_ARRAY_CENTRE_Z_M
    half_t = 0.5 * SOLAR_ARRAY_THICKNESS_M
    solar_array = _grid_box(
        (SOLAR_ARRAY_ROOT_X_M, array_y0, array_z - half_t),
        (SOLAR_ARRAY_ROOT_X_M + SOLAR_ARRAY_LENGTH_M, array_y1, array_z + half_t),
        cell,
    )

    # The yoke runs along the array's root edge and reaches YOKE_OVERLAP_M
    # into the panel: attached, but with no face shared with the panel.
    yoke_x = SOLAR_ARRAY_ROOT_X_M - YOKE_RADIUS_M + YOKE_OVERLAP_M
    boom_tip = (yoke_x, 0.5 * (array_y0 + array_y1), array_z)
    boom = _rod((hx - POST_EMBED_M, BOOM_ROOT_Y_M, array_z), boom_tip, BOOM_RADIUS_M, sections)
    yoke = _rod(
        (yoke_x, array_y0 + YOKE_END_MARGIN_M, array_z),
        (yoke_x, array_y1 - YOKE_END_MARGIN_M, array_z),
        YOKE_RADIUS_M,
        sections,
    )

    asar = _grid_box(
        (-0.5 * ASAR_LENGTH_M, -hy - gap - ASAR_THICKNESS_M, -0.5 * ASAR_HEIGHT_M),
        (0.5 * ASAR_LENGTH_M, -hy - gap, 0.5 * ASAR_HEIGHT_M),
        cell,
    )

    # Ka-band antenna on the zenith face; the mast tip sits inside the shell.
    ka_x, ka_y = KA_POSITION_XY_M
    ka_top_z = -hz - KA_MAST_TOP_ABOVE_FACE_M
    ka_mast = _rod(
        (ka_x, ka_y, -hz + POST_EMBED_M), (ka_x, ka_y, ka_top_z), KA_MAST_RADIUS_M, sections
    )
    ka_seat = _dish_seat_depth(KA_MAST_RADIUS_M, KA_DISH_FOCAL_LENGTH_M)
    ka_dish = _dish(
        (ka_x, ka_y, ka_top_z + ka_seat),
        facing_plus_z=False,
        diameter=KA_DISH_DIAMETER_M,
        focal_length=KA_DISH_FOCAL_LENGTH_M,
        hub_radius=KA_MAST_RADIUS_M,
        settings=settings,
    )

    ring_start = hx - ADAPTER_RING_EMBED_M
    ring_end = hx + ADAPTER_RING_LENGTH_M
    ring = _tube(
        (ring_start, 0.0, 0.0),
        (ring_end, 0.0, 0.0),
        ADAPTER_RING_OUTER_RADIUS_M - ADAPTER_RING_WALL_M,
        ADAPTER_RING_OUTER_RADIUS_M,
        sections,
    )
    flange_end = ring_end - ADAPTER_FLANGE_SETBACK_M
    flange = _tube(
        (flange_end - ADAPTER_FLANGE_LENGTH_M, 0.0, 0.0),
        (flange_end, 0.0, 0.0),
        ADAPTER_FLANGE_RADII_M[0],
        ADAPTER_FLANGE_RADII_M[1],
        sections,
    )

    def nadir_box(spec) -> trimesh.Trimesh:
        x0, x1, y0, y1, height = spec
        return _grid_box((x0, y0, hz + gap), (x1, y1, hz + gap + height), cell)

    ra2_x, ra2_y = RA2_POSITION_XY_M
    ra2_top_z = hz + RA2_PEDESTAL_TOP_ABOVE_FACE_M
    ra2_pedestal = _rod(
        (ra2_x, ra2_y, hz - POST_EMBED_M),
        (ra2_x, ra2_y, ra2_top_z),
        RA2_PEDESTAL_RADIUS_M,
        sections,
    )
    ra2_seat = _dish_seat_depth(RA2_PEDESTAL_RADIUS_M, RA2_DISH_FOCAL_LENGTH_M)
    ra2_dish = _dish(
        (ra2_x, ra2_y, ra2_top_z - ra2_seat),
        facing_plus_z=True,
        diameter=RA2_DISH_DIAMETER_M,
        focal_length=RA2_DISH_FOCAL_LENGTH_M,
        hub_radius=RA2_PEDESTAL_RADIUS_M,
        settings=settings,
    )

    radiators = [
        _grid_box((x0, hy + gap, z0), (x1, hy + gap + RADIATOR_THICKNESS_M, z1), cell)
        for x0, x1, z0, z1 in RADIATORS_PLUS_Y_M
    ] + [
        _grid_box((x0, y0, -hz - gap - RADIATOR_THICKNESS_M), (x1, y1, -hz - gap), cell)
        for x0, x1, y0, y1 in RADIATORS_ZENITH_M
    ]

    return {
        "bus": [bus],
        "solar_array": [solar_array],
        "solar_array_boom": [boom, yoke],
        "asar_antenna": [asar],
        "ka_antenna": [ka_dish],
        "ka_mast": [ka_mast],
        "adapter_ring": [ring, flange],
        "meris": [nadir_box(MERIS_BOX_M)],
        "aatsr": [nadir_box(AATSR_BOX_M)],
        "ra2_antenna": [ra2_pedestal, ra2_dish],
        "radiators": radiators,
    }


def build_envisat(
    detail: str | int = "medium",
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]:
    """Build the Envisat triangle mesh in the body frame.

    Parameters
    ----------
    detail : str or int, default "medium"
        ``"coarse"`` (plain boxes, 12-sided cylinders; 672 triangles),
        ``"medium"`` (9,884 triangles) or ``"fine"`` (95,804 triangles), or
        an integer tessellation factor ``k`` in ``[0, MAX_TESSELLATION_FACTOR]``:
        flat faces are gridded into cells of at most ``1/k`` m (``k = 0``: no
        gridding), cylinders and dishes get ``max(12, 8k)`` sections and dish
        profiles ``max(2, 2k)`` radial rings. The named levels are ``k = 0``,
        ``3`` and ``10``; the triangle count grows roughly as ``950 k**2``.

    Returns
    -------
    vertices : numpy.ndarray, shape (V, 3), float64
        Vertex positions in metres, body frame (see the module docstring).
    faces : numpy.ndarray, shape (F, 3), int64
        Vertex indices of each triangle, counter-clockwise seen from outside,
        so normals point out of the solid.
    face_part : numpy.ndarray, shape (F,), int32
        Index into ``part_names`` of the part each triangle belongs to.
    part_names : tuple of str
        :data:`ENVISAT_PARTS`.

    Raises
    ------
    ValueError, TypeError
        For an invalid ``detail``; see :func:`resolve_detail`.

    Notes
    -----
    Each part is made of one or more closed bodies; vertices are welded within
    a body and never shared between bodies or parts. Faces are grouped by part
    in :data:`ENVISAT_PARTS` order. The output is a pure function of
    ``detail``: the same level gives bit-identical arrays.
    """
    settings = resolve_detail(detail)
    bodies = _part_bodies(settings)

    vertex_blocks = []
    face_blocks = []
    part_blocks = []
    offset = 0
    for part_index, name in enumerate(ENVISAT_PARTS):
        for body in bodies[name]:
            vertex_blocks.append(np.asarray(body.vertices, dtype=np.float64))
            face_blocks.append(np.asarray(body.faces, dtype=np.int64) + offset)
            part_blocks.append(np.full(len(body.faces), part_index, dtype=np.int32))
            offset += len(body.vertices)

    vertices = np.ascontiguousarray(np.concatenate(vertex_blocks), dtype=np.float64)
    faces = np.ascontiguousarray(np.concatenate(face_blocks), dtype=np.int64)
    face_part = np.ascontiguousarray(np.concatenate(part_blocks), dtype=np.int32)
    return vertices, faces, face_part, ENVISAT_PARTS
