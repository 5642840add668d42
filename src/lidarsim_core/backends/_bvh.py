"""Pure-NumPy bounding-volume hierarchy for closest-hit ray/triangle queries.

This is the reference ray backend of lidarsim: no compiled dependencies, float64
throughout, deterministic results.  The tree is a binary BVH built top-down with a
binned surface-area heuristic (SAH), one whole tree level at a time so that the
build is vectorised over all nodes of a level.  Traversal is an ordered
depth-first search with one explicit stack per ray, vectorised over rays: every
iteration advances each still-active ray by exactly one node, so the work per ray
is that of a classic nearest-child-first traversal while the Python overhead is
paid once per iteration for the whole ray batch.
"""

from __future__ import annotations

import numpy as np

__all__ = ["TriangleBVH"]

# Relative slack applied to the far end of ray/box intervals and to the pruning
# distance.  Rounding in the slab test and in the triangle test can otherwise
# reject a box whose contents are hit at (or within a few ulps of) the current
# best distance, which would break exact-tie resolution and edge hits on box
# faces.  A larger value only costs a little extra traversal.
_BOX_SLACK = 1.0 + 1e-10

# Barycentric tolerance: inclusive edge tests so a ray through a shared edge or
# vertex hits at least one of the adjacent triangles (watertight closed meshes).
_BARY_TOL = 1e-12

# Rays whose direction makes |cos(angle to the face normal)| below this value are
# treated as parallel to the face and never hit it.
_PARALLEL_COS = 1e-12

# A triangle is degenerate when |e1 x e2| <= _DEGENERATE_SIN * |e1| * |e2|, that is
# when its two edges are collinear to within rounding.
_DEGENERATE_SIN = 1e-14

# SAH cost model: relative cost of visiting an interior node versus testing one
# triangle.  In NumPy a node visit (two box tests plus stack bookkeeping) costs
# about as much as a couple of vectorised triangle tests.
_SAH_TRAVERSAL_COST = 2.0
_SAH_TRIANGLE_COST = 1.0
_SAH_BINS = 16

_DEFAULT_CHUNK = 32768

# Upper bound on rays * stack depth per chunk (entries of the per-ray stacks), so
# an unusually deep tree shrinks the chunk instead of exhausting memory.
_MAX_STACK_ENTRIES = 1 << 22

# Below this depth the build uses the SAH; deeper nodes (only reached on
# adversarial inputs such as exponentially spaced triangles) are halved by
# count, which bounds the tree depth by about this value plus log2(F).
_SAH_MAX_DEPTH = 64

# Rows of the per-triangle SoA table used by the leaf test.
_V0 = slice(0, 3)
_E1 = slice(3, 6)  # v0 - v1 (note the sign, see _triangle_test)
_E2 = slice(6, 9)  # v2 - v0
_N = slice(9, 12)  # (v1 - v0) x (v2 - v0), unnormalised
_PAR = 12  # parallel threshold: _PARALLEL_COS * |n|


class TriangleBVH:
    """Bounding-volume hierarchy over a triangle mesh with closest-hit queries.

    Build instances with :meth:`build`.  Nodes are stored as flat arrays: for
    every interior node the bounds of its two children are kept together in a
    structure-of-arrays table so a traversal step gathers both child boxes at
    once; leaves reference a contiguous run of a leaf-ordered triangle table.

    Attributes
    ----------
    n_triangles : int
        Number of faces of the input mesh (degenerate faces included).
    n_nodes : int
        Number of BVH nodes (0 when the mesh has no usable triangle).
    depth : int
        Number of levels of the tree (0 for an empty tree).

    Notes
    -----
    Degenerate (zero-area) and non-finite triangles are dropped at build time and
    can never be hit, as are triangles whose edge cross product overflows float64
    (coordinates beyond about 1e150).  Backfaces are not culled.  :meth:`intersect` does not
    modify the tree, so one instance can serve several threads.
    """

    def __init__(
        self,
        n_triangles: int,
        face_normals: np.ndarray,
        root_bounds: np.ndarray,
        child_bounds: np.ndarray,
        first_child: np.ndarray,
        leaf_start: np.ndarray,
        leaf_count: np.ndarray,
        tri_table: np.ndarray,
        tri_face: np.ndarray,
        depth: int,
    ) -> None:
        self.n_triangles = int(n_triangles)
        self._face_normals = face_normals
        self._root_bounds = root_bounds
        self._child_bounds = child_bounds
        self._first_child = first_child
        self._leaf_start = leaf_start
        self._leaf_count = leaf_count
        self._is_leaf = leaf_count > 0
        self._tri_table = tri_table
        self._tri_face = tri_face
        self.depth = int(depth)

    @property
    def n_nodes(self) -> int:
        """int: Number of nodes in the hierarchy."""
        return int(self._first_child.shape[0])

    # ------------------------------------------------------------------ build

    @classmethod
    def build(
        cls, vertices: np.ndarray, faces: np.ndarray, leaf_size: int = 8
    ) -> "TriangleBVH":
        """Build a BVH over a triangle mesh.

        Parameters
        ----------
        vertices : numpy.ndarray
            ``(V, 3)`` vertex coordinates, converted to float64.
        faces : numpy.ndarray
            ``(F, 3)`` integer vertex indices per triangle.
        leaf_size : int, optional
            Maximum number of triangles per leaf (>= 1); the SAH cost model
            usually stops splitting earlier, at about 2 to 4 triangles.

        Returns
        -------
        TriangleBVH
            The hierarchy, ready for :meth:`intersect`.

        Raises
        ------
        ValueError
            If the arrays have the wrong shape, a face index is out of range or
            ``leaf_size`` is smaller than 1.
        """
        vertices, faces = _validate_mesh(vertices, faces)
        if int(leaf_size) < 1:
            raise ValueError(f"leaf_size must be >= 1, got {leaf_size}")
        leaf_size = int(leaf_size)

        # Huge (but finite) coordinates may overflow areas and lengths to inf;
        # such triangles are dropped or just get a poor split, never a warning.
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            p0, e1, e2, normal, nlen, usable = _triangle_geometry(vertices, faces)
            face_normals = np.full((faces.shape[0], 3), np.nan)
            face_normals[usable] = normal[usable] / nlen[usable, None]
            ids = np.flatnonzero(usable)
            if ids.size == 0:
                return cls._empty(faces.shape[0], face_normals)
            # Bounds from the stored vertices themselves (not v0 + edge, which
            # rounds) so every box exactly contains its triangles.
            c0, c1, c2 = (vertices.take(faces[ids, j], axis=0) for j in range(3))
            tri_lo = np.minimum(np.minimum(c0, c1), c2)
            tri_hi = np.maximum(np.maximum(c0, c1), c2)
            tree = _build_tree(tri_lo, tri_hi, leaf_size)
        order = ids[tree["perm"]]

        tri_table = np.empty((13, order.size))
        tri_table[_V0] = p0[order].T
        tri_table[_E1] = -e1[order].T
        tri_table[_E2] = e2[order].T
        tri_table[_N] = normal[order].T
        tri_table[_PAR] = _PARALLEL_COS * nlen[order]

        root_bounds = np.stack([tree["lo"][0], tree["hi"][0]])  # (2, 3)
        return cls(
            n_triangles=faces.shape[0],
            face_normals=face_normals,
            root_bounds=root_bounds,
            child_bounds=_child_bound_table(tree["lo"], tree["hi"], tree["first_child"]),
            first_child=tree["first_child"],
            leaf_start=tree["leaf_start"],
            leaf_count=tree["leaf_count"],
            tri_table=np.ascontiguousarray(tri_table),
            tri_face=order.astype(np.int64),
            depth=tree["depth"],
        )

    @classmethod
    def _empty(cls, n_triangles: int, face_normals: np.ndarray) -> "TriangleBVH":
        """Return a tree without nodes: every ray misses."""
        return cls(
            n_triangles=n_triangles,
            face_normals=face_normals,
            root_bounds=np.zeros((2, 3)),
            child_bounds=np.zeros((12, 0)),
            first_child=np.zeros(0, np.int64),
            leaf_start=np.zeros(0, np.int64),
            leaf_count=np.zeros(0, np.int64),
            tri_table=np.zeros((13, 0)),
            tri_face=np.zeros(0, np.int64),
            depth=0,
        )

    # -------------------------------------------------------------- intersect

    def intersect(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        t_min: float = 1e-9,
        t_max: float = np.inf,
        chunk_size: int = _DEFAULT_CHUNK,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Find the closest triangle hit of every ray.

        Parameters
        ----------
        origins : numpy.ndarray
            ``(N, 3)`` ray origins, converted to float64.
        directions : numpy.ndarray
            ``(N, 3)`` unit ray directions, converted to float64.  They are not
            renormalised: the returned distance is the ray parameter ``t`` of
            ``origin + t * direction``, a distance only for unit directions.
        t_min : float, optional
            Hits must satisfy ``t > t_min`` (must be finite and >= 0).
        t_max : float, optional
            Hits must satisfy ``t <= t_max``.
        chunk_size : int, optional
            Number of rays traversed together; bounds the memory of the per-ray
            stacks and work arrays.

        Returns
        -------
        distance : numpy.ndarray
            ``(N,)`` float64 hit distance, NaN where the ray misses.
        face : numpy.ndarray
            ``(N,)`` int64 index of the hit face in the input ``faces``, -1 on miss.
        normal : numpy.ndarray
            ``(N, 3)`` float64 unit geometric normal ``normalize((v1-v0) x (v2-v0))``
            of the hit face (not flipped toward the ray), NaN on miss.

        Raises
        ------
        ValueError
            On badly shaped inputs or invalid ``t_min``/``t_max``/``chunk_size``.

        Notes
        -----
        The closest hit wins; hits at exactly the same distance resolve to the
        lowest face index.  Rays with non-finite or zero direction, or non-finite
        origin, miss.
        """
        origins, directions = _validate_rays(origins, directions)
        t_min, t_max = _validate_range(t_min, t_max)
        if int(chunk_size) < 1:
            raise ValueError(f"chunk_size must be >= 1, got {chunk_size}")
        n = origins.shape[0]
        dist = np.full(n, np.nan)
        face = np.full(n, -1, dtype=np.int64)
        if n == 0 or self.n_nodes == 0 or t_max < t_min:
            return dist, face, np.full((n, 3), np.nan)

        step = max(1, min(int(chunk_size), _MAX_STACK_ENTRIES // max(self.depth, 1)))
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            for lo in range(0, n, step):
                hi = min(lo + step, n)
                batch = _RayBatch(origins[lo:hi], directions[lo:hi], t_min, t_max, self.depth)
                _Traversal(self, batch).run()
                hit = batch.face != _NO_FACE
                dist[lo:hi][hit] = batch.t_best[hit]
                face[lo:hi][hit] = batch.face[hit]
        normal = np.full((n, 3), np.nan)
        hit = face >= 0
        normal[hit] = self._face_normals[face[hit]]
        return dist, face, normal


# ---------------------------------------------------------------- traversal
#
# Everything in the hot loop is a 1-D contiguous array accessed with the
# ndarray.take / ndarray.put methods and updated in place where possible: 2-D
# fancy indexing and boolean-mask indexing are several times slower in NumPy.

_NO_FACE = np.iinfo(np.int64).max


class _RayBatch:
    """Per-ray traversal state of one chunk of rays.

    ``face`` holds the best face id so far, ``_NO_FACE`` meaning none yet: as
    the largest int64 it lets the "lower face id wins" tie rule work unchanged
    before the first hit.  Stacks are level-major (``slot = level * n + ray``)
    so rays pushing at the same level write close together.
    """

    def __init__(self, origins, directions, t_min, t_max, depth):
        n = origins.shape[0]
        self.n = n
        self.o = [np.ascontiguousarray(origins[:, k]) for k in range(3)]
        self.d = [np.ascontiguousarray(directions[:, k]) for k in range(3)]
        # 1/0 = +-inf is intended; see _box_test for how it is handled.
        self.inv = [1.0 / dk for dk in self.d]
        self.t_min = t_min
        self.t_best = np.full(n, t_max)
        self.face = np.full(n, _NO_FACE, dtype=np.int64)
        self.cur = np.zeros(n, dtype=np.int64)
        self.sp = np.zeros(n, dtype=np.int64)
        self.stack_node = np.empty(max(depth, 1) * n, dtype=np.int64)
        self.stack_t = np.empty(max(depth, 1) * n)
        self.alive = np.zeros(n, dtype=bool)

    def usable(self):
        """Mask of rays with finite origin and finite, non-zero direction."""
        ok = np.ones(self.n, dtype=bool)
        for k in range(3):
            ok &= np.isfinite(self.o[k]) & np.isfinite(self.d[k])
        return ok & ((self.d[0] != 0) | (self.d[1] != 0) | (self.d[2] != 0))


class _Traversal:
    """Ordered depth-first traversal of one :class:`_RayBatch`.

    Each iteration moves every active ray by one node: rays on an interior node
    test both children and descend into the nearer hit child (pushing the other
    one), rays on a leaf test its triangles; rays with nothing left to visit pop
    their stack, skipping entries farther than their current best hit.
    """

    def __init__(self, bvh: TriangleBVH, batch: _RayBatch) -> None:
        self.bvh = bvh
        self.b = batch

    def run(self) -> None:
        """Traverse until every ray has exhausted its stack."""
        b, bvh = self.b, self.bvh
        rb = bvh._root_bounds
        _, hit = _box_test(rb[0], rb[1], b.o, b.inv, b.t_min, b.t_best)
        act = np.flatnonzero(hit & b.usable())
        b.alive[act] = True
        while act.size:
            leaf = bvh._is_leaf.take(b.cur.take(act))
            at_leaf = act.take(np.flatnonzero(leaf))
            at_inner = act.take(np.flatnonzero(~leaf))
            stuck = self._inner_step(at_inner)
            self._leaf_step(at_leaf)
            self._pop(np.concatenate([stuck, at_leaf]))
            act = act.take(np.flatnonzero(b.alive.take(act)))

    def _inner_step(self, rays: np.ndarray) -> np.ndarray:
        """Advance rays on interior nodes; return those where no child is hit."""
        b, bvh = self.b, self.bvh
        if rays.size == 0:
            return rays
        node = b.cur.take(rays)
        o = [ok.take(rays) for ok in b.o]
        inv = [ik.take(rays) for ik in b.inv]
        t_best = b.t_best.take(rays)
        cb = bvh._child_bounds
        lo0 = [cb[2 * k].take(node) for k in range(3)]
        hi0 = [cb[6 + 2 * k].take(node) for k in range(3)]
        lo1 = [cb[2 * k + 1].take(node) for k in range(3)]
        hi1 = [cb[7 + 2 * k].take(node) for k in range(3)]
        tn0, h0 = _box_test(lo0, hi0, o, inv, b.t_min, t_best)
        tn1, h1 = _box_test(lo1, hi1, o, inv, b.t_min, t_best)

        # Descend into the nearer hit child now; push the farther one with its
        # entry distance so it can be skipped at pop time if a closer hit turns up.
        both = h0 & h1
        second_nearer = tn1 < tn0
        first = bvh._first_child.take(node)
        b.cur.put(rays, first + np.where(both, second_nearer, h1))
        pushed = np.flatnonzero(both)
        if pushed.size:
            r = rays.take(pushed)
            far = ~second_nearer.take(pushed)
            sp = b.sp.take(r)
            slot = sp * b.n + r
            b.stack_node.put(slot, first.take(pushed) + far)
            b.stack_t.put(slot, np.where(far, tn1.take(pushed), tn0.take(pushed)))
            b.sp.put(r, sp + 1)
        return rays.take(np.flatnonzero(~(h0 | h1)))

    def _leaf_step(self, rays: np.ndarray) -> None:
        """Test rays on leaves against every triangle of their leaf."""
        b, bvh = self.b, self.bvh
        if rays.size == 0:
            return
        node = b.cur.take(rays)
        count = bvh._leaf_count.take(node)
        offsets = np.cumsum(count) - count
        n_pairs = int(offsets[-1] + count[-1])
        # (ray, triangle) pairs, grouped by ray so reduceat gives per-ray minima.
        pair_ray = np.repeat(np.arange(rays.size), count)
        tri = np.repeat(bvh._leaf_start.take(node) - offsets, count)
        tri += np.arange(n_pairs)
        ray = rays.take(pair_ray)
        o = [ok.take(ray) for ok in b.o]
        d = [dk.take(ray) for dk in b.d]
        table = [row.take(tri) for row in bvh._tri_table]
        t = _triangle_test(table, o, d, b.t_min)

        t_leaf = np.minimum.reduceat(t, offsets)
        # Among the pairs at a ray's minimum distance keep the lowest face id.
        at_min = t == t_leaf.take(pair_ray)
        cand = np.where(at_min, bvh._tri_face.take(tri), _NO_FACE)
        f_leaf = np.minimum.reduceat(cand, offsets)
        t_best = b.t_best.take(rays)
        better = (t_leaf < t_best) | ((t_leaf == t_best) & (f_leaf < b.face.take(rays)))
        better &= t_leaf < np.inf  # an all-miss leaf yields t = inf with a real face id
        win = np.flatnonzero(better)
        r = rays.take(win)
        b.t_best.put(r, t_leaf.take(win))
        b.face.put(r, f_leaf.take(win))

    def _pop(self, rays: np.ndarray) -> None:
        """Pop the next stacked node of ``rays``; retire rays whose stack runs out.

        Entries whose box starts beyond the ray's best hit are discarded.
        """
        b = self.b
        while rays.size:
            sp = b.sp.take(rays)
            empty = sp == 0
            b.alive.put(rays.take(np.flatnonzero(empty)), False)
            keep = np.flatnonzero(~empty)
            rays = rays.take(keep)
            sp = sp.take(keep) - 1
            b.sp.put(rays, sp)
            slot = sp * b.n + rays
            near = b.stack_t.take(slot) <= b.t_best.take(rays) * _BOX_SLACK
            ok = np.flatnonzero(near)
            b.cur.put(rays.take(ok), b.stack_node.take(slot.take(ok)))
            rays = rays.take(np.flatnonzero(~near))


def _box_test(lo, hi, o, inv, t_min, t_best):
    """Slab test of rays against boxes, per-axis 1-D arrays (or scalars).

    Returns the entry distance (clamped to ``t_min``) and the hit mask.  A hit
    needs ``max(entry, t_min) <= min(exit, t_best)`` up to the relative slack
    ``_BOX_SLACK``.

    A zero direction component gives ``inv = +-inf``; when the origin lies exactly
    on that slab plane the product is ``0 * inf = NaN``.  ``minimum``/``maximum``
    propagate that NaN and ``fmax``/``fmin`` then ignore it, so the axis imposes
    no constraint, which is right because the ray runs inside the closed slab.
    """
    tnear = tfar = None
    for k in range(3):
        ta = lo[k] - o[k]
        ta *= inv[k]
        tb = hi[k] - o[k]
        tb *= inv[k]
        t_lo = np.minimum(ta, tb)
        t_hi = np.maximum(ta, tb, out=ta)
        if tnear is None:
            tnear = np.fmax(t_lo, t_min)
            tfar = np.fmin(t_hi, t_best)
        else:
            np.fmax(tnear, t_lo, out=tnear)
            np.fmin(tfar, t_hi, out=tfar)
    tfar *= _BOX_SLACK
    return tnear, tnear <= tfar


def _triangle_test(tri, o, d, t_min):
    """Ray/triangle distances for ``(ray, triangle)`` pairs, ``inf`` on miss.

    Moeller-Trumbore in the precomputed-normal form: with ``s = o - v0``,
    ``r = d x s``, ``n = (v1 - v0) x (v2 - v0)`` and ``den = d . n`` the
    barycentrics are ``u = ((v2 - v0) . r) / den``, ``v = ((v0 - v1) . r) / den``
    and the distance ``t = -(s . n) / den``.  Working relative to ``v0`` keeps
    far-away origins and coordinates accurate in float64.
    """
    sx = o[0] - tri[0]
    sy = o[1] - tri[1]
    sz = o[2] - tri[2]
    dx, dy, dz = d
    rx = dy * sz - dz * sy
    ry = dz * sx - dx * sz
    rz = dx * sy - dy * sx
    nx, ny, nz = tri[9], tri[10], tri[11]
    den = dx * nx + dy * ny + dz * nz
    # The minus sign is folded into the reciprocal, so u and v below are the
    # negated barycentrics and their tests are mirrored accordingly.
    inv_den = -1.0 / den
    t = (sx * nx + sy * ny + sz * nz) * inv_den
    u = (tri[6] * rx + tri[7] * ry + tri[8] * rz) * inv_den
    v = (tri[3] * rx + tri[4] * ry + tri[5] * rz) * inv_den
    ok = np.abs(den) > tri[_PAR]
    ok &= u <= _BARY_TOL
    ok &= v <= _BARY_TOL
    ok &= u + v >= -1.0 - _BARY_TOL
    ok &= t > t_min
    return np.where(ok, t, np.inf)


# ------------------------------------------------------------------------ build


def _triangle_geometry(vertices, faces):
    """Per-face ``v0``, edges, unnormalised normal, its length and usability.

    A face is usable when its vertices are finite and it is not degenerate, i.e.
    ``|e1 x e2| > _DEGENERATE_SIN * |e1| * |e2|`` with everything finite.
    """
    p0 = vertices.take(faces[:, 0], axis=0)
    e1 = vertices.take(faces[:, 1], axis=0) - p0
    e2 = vertices.take(faces[:, 2], axis=0) - p0
    normal = np.cross(e1, e2)
    nlen = np.sqrt(np.einsum("ij,ij->i", normal, normal))
    scale = np.sqrt(np.einsum("ij,ij->i", e1, e1)) * np.sqrt(np.einsum("ij,ij->i", e2, e2))
    usable = (nlen > _DEGENERATE_SIN * scale) & np.isfinite(nlen) & np.isfinite(scale)
    usable &= np.isfinite(p0[:, 0]) & np.isfinite(p0[:, 1]) & np.isfinite(p0[:, 2])
    return p0, e1, e2, normal, nlen, usable


def _build_tree(tri_lo: np.ndarray, tri_hi: np.ndarray, leaf_size: int) -> dict:
    """Top-down binned-SAH build, vectorised over all nodes of one tree level.

    Each node owns a contiguous range of ``perm``; splitting a node partitions
    its range in place, so leaf ranges end up contiguous in ``perm`` order.
    Children of a node are allocated as a consecutive pair.
    """
    m = tri_lo.shape[0]
    cent = 0.5 * tri_lo + 0.5 * tri_hi  # not (lo + hi) / 2, which can overflow
    perm = np.arange(m)
    cap = 2 * m - 1
    node_lo = np.empty((cap, 3))
    node_hi = np.empty((cap, 3))
    first_child = np.full(cap, -1, dtype=np.int64)
    leaf_start = np.zeros(cap, dtype=np.int64)
    leaf_count = np.zeros(cap, dtype=np.int64)

    act_id = np.zeros(1, dtype=np.int64)
    act_start = np.zeros(1, dtype=np.int64)
    act_count = np.full(1, m, dtype=np.int64)
    n_nodes = 1
    depth = 0
    while act_id.size:
        depth += 1
        offsets = np.cumsum(act_count) - act_count
        total = int(offsets[-1] + act_count[-1])
        seg = np.repeat(np.arange(act_id.size), act_count)
        local = np.arange(total) - np.take(offsets, seg)
        tri = np.take(perm, np.take(act_start, seg) + local)
        lo = np.take(tri_lo, tri, axis=0)
        hi = np.take(tri_hi, tri, axis=0)
        c = np.take(cent, tri, axis=0)

        nlo = np.minimum.reduceat(lo, offsets, axis=0)
        nhi = np.maximum.reduceat(hi, offsets, axis=0)
        node_lo[act_id] = nlo
        node_hi[act_id] = nhi

        bins, axis, split_bin, split_cost = _best_splits(lo, hi, c, seg, offsets, act_count)
        with np.errstate(invalid="ignore", divide="ignore"):
            rel_cost = split_cost / _half_area(nlo.T, nhi.T)
        sah_split = _SAH_TRAVERSAL_COST + _SAH_TRIANGLE_COST * rel_cost
        sah_leaf = _SAH_TRIANGLE_COST * act_count
        make_leaf = (act_count <= leaf_size) & ~(sah_split < sah_leaf)
        make_leaf |= act_count <= 1

        leaf_id = act_id[make_leaf]
        leaf_start[leaf_id] = act_start[make_leaf]
        leaf_count[leaf_id] = act_count[make_leaf]

        split = ~make_leaf
        if not split.any():
            break
        # No SAH split exists when all centroids coincide: halve by position.
        median = split & (~np.isfinite(split_cost) | (depth > _SAH_MAX_DEPTH))
        tri_bin = np.take(bins.ravel(), 3 * np.arange(total) + np.take(axis, seg))
        goes_left = tri_bin <= np.take(split_bin, seg)
        halves = local < np.take(act_count // 2, seg)
        goes_left = np.where(np.take(median, seg), halves, goes_left)

        # Stable in-place partition of every node range: lefts first, then rights.
        n_left = np.add.reduceat(goes_left.astype(np.int64), offsets)
        lefts_before = np.cumsum(goes_left) - goes_left
        left_rank = lefts_before - np.take(np.take(lefts_before, offsets), seg)
        new_local = np.where(goes_left, left_rank, np.take(n_left, seg) + (local - left_rank))
        moving = np.flatnonzero(np.take(split, seg))
        dest = np.take(act_start, np.take(seg, moving)) + np.take(new_local, moving)
        perm[dest] = np.take(tri, moving)

        k = int(split.sum())
        children = n_nodes + 2 * np.arange(k, dtype=np.int64)
        first_child[act_id[split]] = children
        n_nodes += 2 * k
        s_start, s_count, s_left = act_start[split], act_count[split], n_left[split]
        act_id = np.stack([children, children + 1], axis=1).ravel()
        act_start = np.stack([s_start, s_start + s_left], axis=1).ravel()
        act_count = np.stack([s_left, s_count - s_left], axis=1).ravel()

    return {
        "perm": perm,
        "lo": node_lo[:n_nodes],
        "hi": node_hi[:n_nodes],
        "first_child": first_child[:n_nodes],
        "leaf_start": leaf_start[:n_nodes],
        "leaf_count": leaf_count[:n_nodes],
        "depth": depth,
    }


def _best_splits(lo, hi, cent, seg, offsets, count):
    """Binned SAH: best split plane of every node of a level.

    Returns the per-triangle bin indices ``(T, 3)``, and per node the split axis,
    the last bin going left, and the unnormalised SAH cost
    ``area(L) * n(L) + area(R) * n(R)`` (``inf`` when no split separates anything).
    """
    n = offsets.size
    # More bins than triangles per node buys nothing; deep levels hold many small
    # nodes, where fewer bins make the per-bin arrays (the build's main cost) small.
    nb = int(np.clip(np.ceil(count.mean()), 2, _SAH_BINS))
    clo = np.minimum.reduceat(cent, offsets, axis=0)
    chi = np.maximum.reduceat(cent, offsets, axis=0)
    ext = chi - clo
    with np.errstate(divide="ignore"):
        scale = np.where(ext > 0, nb / ext, 0.0)
    bins = (cent - np.take(clo, seg, axis=0)) * np.take(scale, seg, axis=0)
    bins = bins.astype(np.int64)
    np.clip(bins, 0, nb - 1, out=bins)

    # One flat bin id per (bin, axis, node), all three axes in one scatter pass.
    # Bins lead so the prefix sweeps below run over contiguous blocks.
    key = ((bins.T * 3 + np.arange(3)[:, None]) * n + seg[None, :]).ravel()
    size = nb * 3 * n
    cnt = np.bincount(key, minlength=size).reshape(nb, 3, n)
    left_lo, right_lo, left_hi, right_hi = [], [], [], []
    for j in range(3):
        blo = np.full(size, np.inf)
        bhi = np.full(size, -np.inf)
        np.minimum.at(blo, key, np.tile(lo[:, j], 3))
        np.maximum.at(bhi, key, np.tile(hi[:, j], 3))
        blo = blo.reshape(nb, 3, n)
        bhi = bhi.reshape(nb, 3, n)
        left_lo.append(_sweep(np.minimum, blo)[:-1])
        left_hi.append(_sweep(np.maximum, bhi)[:-1])
        right_lo.append(_sweep(np.minimum, blo[::-1])[-2::-1])
        right_hi.append(_sweep(np.maximum, bhi[::-1])[-2::-1])

    # Split "after bin i" for i < nb - 1: left = bins[:i+1], right = bins[i+1:].
    n_left = np.cumsum(cnt, axis=0)[:-1]
    n_right = count[None, None, :] - n_left
    with np.errstate(invalid="ignore"):
        cost = _half_area(left_lo, left_hi) * n_left + _half_area(right_lo, right_hi) * n_right
    cost = np.where((n_left > 0) & (n_right > 0), cost, np.inf)  # (nb - 1, 3, n)

    flat = cost.reshape(3 * (nb - 1), n)
    best = np.argmin(flat, axis=0)
    best_cost = flat[best, np.arange(n)]
    return bins, best % 3, best // 3, best_cost


def _sweep(ufunc, a):
    """Inclusive prefix reduction along axis 0, one contiguous slab at a time.

    Faster than ``ufunc.accumulate(a, axis=0)``, which NumPy runs element-wise
    along the strided axis.
    """
    out = np.empty_like(a)
    out[0] = a[0]
    for i in range(1, a.shape[0]):
        ufunc(out[i - 1], a[i], out=out[i])
    return out


def _half_area(lo, hi):
    """Half surface area of boxes given as per-axis corner arrays ``lo[k]``, ``hi[k]``."""
    ex = hi[0] - lo[0]
    ey = hi[1] - lo[1]
    ez = hi[2] - lo[2]
    return ex * ey + ey * ez + ez * ex


def _child_bound_table(lo, hi, first_child):
    """``(12, n_nodes)`` SoA table of both children's boxes per interior node.

    Row ``lohi * 6 + axis * 2 + child`` so a gathered block reshapes to
    ``(lo/hi, axis, child, rays)``.
    """
    n = first_child.shape[0]
    table = np.zeros((2, 3, 2, n))
    inner = first_child >= 0
    c = first_child[inner]
    for child in (0, 1):
        table[0, :, child, inner] = lo[c + child]
        table[1, :, child, inner] = hi[c + child]
    return np.ascontiguousarray(table.reshape(12, n))


# ------------------------------------------------------------------- validation


def _validate_mesh(vertices, faces):
    """Return float64 ``(V, 3)`` vertices and int64 ``(F, 3)`` faces or raise."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"vertices must have shape (V, 3), got {vertices.shape}")
    if faces.size == 0:
        faces = faces.reshape(0, 3)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"faces must have shape (F, 3), got {faces.shape}")
    if faces.size and not np.issubdtype(faces.dtype, np.integer):
        raise ValueError(f"faces must be integer, got dtype {faces.dtype}")
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    if faces.size and (faces.min() < 0 or faces.max() >= vertices.shape[0]):
        raise ValueError("faces reference vertices out of range")
    return vertices, faces


def _validate_rays(origins, directions):
    """Return float64 ``(N, 3)`` origins and directions or raise."""
    origins = np.ascontiguousarray(origins, dtype=np.float64)
    directions = np.ascontiguousarray(directions, dtype=np.float64)
    if origins.size == 0 and directions.size == 0:
        return origins.reshape(0, 3), directions.reshape(0, 3)
    if origins.ndim != 2 or origins.shape[1] != 3:
        raise ValueError(f"origins must have shape (N, 3), got {origins.shape}")
    if directions.shape != origins.shape:
        raise ValueError(
            f"directions must have the shape of origins {origins.shape}, got {directions.shape}"
        )
    return origins, directions


def _validate_range(t_min, t_max):
    """Return ``(t_min, t_max)`` as floats or raise on an invalid interval."""
    t_min = float(t_min)
    t_max = float(t_max)
    if not np.isfinite(t_min) or t_min < 0.0:
        raise ValueError(f"t_min must be finite and >= 0, got {t_min}")
    if np.isnan(t_max):
        raise ValueError("t_max must not be NaN")
    return t_min, t_max
