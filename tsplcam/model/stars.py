"""Star points (extraordinary points) of T-splines: the surface on the two rings of faces
around them, by subdividing to the regular level.

Around a star point S of valence n the T-spline's blending functions are not all tensor
B-splines: the functions of S and of its 2n neighbours (the spoke vertices s_j and the
diagonal vertices q_j of its faces, together W0) wrap around S, where no single knot frame
exists. They are defined by the T-NURCC rule (Sederberg et al. 1998, 2003): refinement.
Every other function is the T-spline's own (ray-cast knots), T-junctions and all.

The construction, in sector charts (sector j: S at the origin, x along spoke j, y along
spoke j+1; the first face F_j is [0, d_j] x [0, d_(j+1)], d_j the spoke's knot interval):

* Each W0 function is split into its 25 children of the halved knot vector (exact midpoint
  knot insertion, per direction). Children at the level-1 nodes next to S (the new spoke
  and face points, W1) are summed into one function per node; the new point at S itself is
  the NURCC vertex rule (Sederberg et al. 1998, eq. 16-18: (n-3)/n S + 3/(n sum(m+f))
  sum(m_i M_i + f_i F_i), M_i the spoke midpoints, F_i the face points, m_i =
  (d_(i-1) + d_(i+1))(d_(i-2) + d_(i+2))/2, f_i = d_(i-1) d_(i+2)); all other children are
  plain B-splines from then on. The same step takes W1 to W2 and so on. With uniform
  intervals this is exactly Catmull-Clark.
* The knot interval "behind" S along spoke j (which a ray through S would need) is
  b_j = (d_(j+2) + d_(j-2)) / 2, the mean of the spokes two steps away (the NURCC rule; for
  valence 4 it is the opposite spoke). It serves the rules and the children on spoke j
  itself; children on the rows through the neighbouring spokes' vertices cross those
  spokes at regular vertices, where the T-mesh itself gives d_(j+2) and d_(j-2)
  (``children``): so every child is the refined T-mesh's own B-spline and the functions
  stay a partition of unity for any spoke intervals. The W_k spoke functions, where they
  are evaluated directly (the level-k ring of faces of sector j + 1), are seen with d_(j+2)
  behind S as well (``to_chart``): with b_j they would reach the ring there once
  b_j > 2 d_(j+2), where their refinement does not (gaps up to 1.6e-3 of the
  model size at spoke ratios up to 10).
* The NURCC rules with unequal spoke intervals can have two different subdominant
  eigenvalues (valence 8, intervals in ratio 4: 0.72 and 0.57 with 0.52 next), so that the
  normal at S converges too slowly or not at all (the defect that Li, Finnigan and
  Sederberg 2016, "G1 non-uniform Catmull-Clark surfaces", address with eigen-polyhedra).
  Here the NURCC rules make levels 1 and 2, and the star's own points follow
  Catmull-Clark's rules from level 2 on: its stationary matrix then has Catmull-Clark's
  double subdominant eigenvalue, so the limit is G1 at S whatever the intervals. Only the
  points next to S change (the functions and their knots do not), so the surface stays C2
  away from S, and uniform stars are still exactly Catmull-Clark. At valence 4 the rules
  are knot insertion throughout (``tspline_model(subdivide_at=...)`` checks that the
  construction then gives the T-spline's own surface).
* The knot lines beyond the star's neighbours must run on across its second ring (one knot
  vector per level-1 function). Where a T-junction cuts them, local knot insertion extends
  them first (``clear_t_junctions``, the T-NURCC way): the neighbours' functions split
  exactly into refined ones and plain B-splines, and the faces the star's function still
  reaches beyond the second ring join the zone. A zero interval there is refused by name.
* T-junctions in the star's first ring: one in the middle of an outer side of a face F_j
  (its knot is a knot of the refined star, on the level-1 grid), and spoke or diagonal
  vertices that are T-junctions themselves. The T-junction's own function wraps around S (it
  joins W0, ``StarZone.extra``) and it cuts the rays of the neighbours beside it. The
  construction runs on the star as if those rays were not cut (``_ring1_functions``); the
  exact difference, actual functions minus those, is refined to level 1 on its own
  (``_level1_parts``: every piece is a level-1 function of the star or a plain B-spline),
  its pieces on a spoke's row with b_k behind S whatever their sector (and those at S with
  b_k behind it along the spoke k of the T-junction that changed them), so that the
  differences are those of one valence-4 configuration and sum to what the T-junctions
  change: the level-1 rows stay affine and the functions a partition of unity at any
  valence. At valence 4 the sum is the T-spline's own. A spoke vertex that is a T-junction
  leaves a second-ring face across the spoke: it is charted in sector j, whose chart holds
  both sides.
* A first-ring T-junction off its side's middle, at the fraction r of the side from the
  spoke (``_levelm_parts``): the differences are refined (exactly, by knot insertion) onto
  a graded grid that is the star's level-m grid next to S, m the first level at which r is
  a grid knot (k/2^m) or lies three level-m intervals or more from the spoke (so no piece
  around S holds the T-junction's knot; m <= ``MAX_TJ_LEVEL``, nearer ones are refused).
  Each T-junction's differences are taken in its own face's sector chart (what it changes
  beyond the star's functions lies in the half-planes ahead of S there), and each piece
  with its coefficient from the knot intervals its row and column see there (``_frame``:
  b_s along spoke s on the spoke's row, the sectors' intervals elsewhere, b_k at S along
  the T-junction's spoke k), so that the pieces at one place are one function and their
  coefficients those of one valence-4 configuration. Pieces at the level-m points next to
  S join W_m (level 2: the rows; deeper: ``StarLevels`` adds them to the configuration of
  their level), the others are plain B-splines; pieces behind S (the quadrant opposite the
  face, the sector j + 2 at valence 4) have no place at other valences and are left out:
  their coefficients sum to zero, so the functions stay a partition of unity. Spokes whose
  T-junctions all sit at their sides' middles keep the level-1 path above (when all the
  star's do). A side may hold several T-junctions. A function whose rays meet T-junctions
  of several faces changes one ray at a time (middle ones first), each step in its
  T-junction's face's chart. Where both faces at a spoke have T-junctions, the functions
  along the line across the spoke (the diagonal vertices beside it, the T-junctions' own)
  see one face's or both: their changes are taken face after face in index order (the
  order of every function's steps), each the change that face's T-junctions make to the
  layout with the earlier face's (``_two_faced``: the knots with the first face's
  T-junctions only). A diagonal whose rays meet T-junctions on both sides of S loads from
  valence 4 on (at valence 4 the T-spline's own; such layouts are not analysis-suitable);
  refused by name at valence 3, where the valence-4 copy with those faces next to each
  other is suitable and the construction missed the partition of unity by 1.4e-2.
* W_k functions reach only 1.5 level-k intervals from S, so the two rings of faces around
  S (the zone) contain every piece that is not a plain B-spline: the surface there is
  the sum of plain B-splines (the other functions, and the children split off at every
  level) plus the W_k functions of the level whose ring [2, 4] x 2^-k the point falls in.
  Outside the zone the W0 functions are their ray-cast B-splines, so the surface joins
  the rest of the T-spline C2.
* From level 2 on, every knot near S is a scaled copy of the spoke intervals: one
  stationary matrix A takes the level-k configuration (W_k and the accumulated children
  within 5 intervals, 1 + 30 n functions) to level k+1. Configurations are precomputed
  level by level (as differences from the limit point, ``cells.LevelCells``' method).

``find_stars(walker)`` finds and checks the stars; ``build_zone`` makes one star's
construction (``StarZone``); ``StarLevels`` holds its subdivided part, ``StarCells``
evaluates it on the star's first faces (array calls: one product per cell and level met).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ..errors import InputError
from .basis import bernstein
from .cells import DERIVS, _chain, bicubic_nets, scale_derivatives
from .twalk import Walker, apply, compose, inverse, map_knots, rot

MAX_LEVEL = 56                 # below 2^-56 of a face the point is the limit point
EPS_LEVEL = 50                 # derivatives at S itself are taken this close to it (as LevelCells)
NET_LEVEL = 24                 # levels 2 .. NET_LEVEL are kept as Bezier nets (StarLevels)
RADIUS = 5                     # configuration nodes per sector: 0..5 along x and y
MAX_TJ_LEVEL = 10              # first-face T-junctions at 3/2^m of their side or further (tj_level)


# -- one-dimensional midpoint refinement -------------------------------------------------
def _split(knots: tuple) -> tuple[np.ndarray, np.ndarray]:
    """The cubic B-spline N[t0..t4] as a combination of the B-splines of its knot vector with
    every positive interval halved (zero intervals stay zero, as in the refined T-mesh):
    (children knots (k + 1, 5), coefficients (k + 1,)) for k positive intervals, by Boehm's
    knot insertion (one midpoint at a time, exact up to rounding)."""
    return _split_keeping(knots, (), 0.0)


def split(knots: np.ndarray):
    return _split(tuple(float(x) for x in knots))


@lru_cache(maxsize=None)
def _split_keeping(knots: tuple, keep: tuple, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """``_split`` with the intervals next to the knots ``keep`` (within tol) left whole: there
    a first face's T-junction already halves an interval, its knot is one of the refined
    star's. The midpoints inserted by ``_boehm``."""
    t = [float(x) for x in knots]
    half = [t[i + 1] > t[i] and not any(min(abs(t[i] - k), abs(t[i + 1] - k)) <= tol for k in keep)
            for i in range(4)]
    return _boehm(t, [(t[i] + t[i + 1]) / 2 for i in range(4) if half[i]])


@dataclass
class Fn:
    """A tensor B-spline in sector chart ``sector``: centre (x, y), knots (5,) per direction,
    and its coefficient row over the star's W0 control points (homogeneous)."""
    sector: int
    cx: float
    cy: float
    xk: np.ndarray
    yk: np.ndarray
    row: np.ndarray


def _canon(n: int, sector: int, x: float, y: float, xk, yk):
    """A node given in ``sector``'s chart, re-expressed in the chart of the sector it lies
    in (x > 0, y >= 0; points on spoke j belong to sector j), with its knots; None behind S."""
    tol = 1e-12 * (1.0 + abs(x) + abs(y))
    if x > tol and y >= -tol:
        return sector, x, max(y, 0.0), xk, yk
    if x <= tol and y > tol:           # sector + 1: x' = y, y' = -x
        xk2, yk2 = map_knots(np.asarray(xk), np.asarray(yk), (3, 0.0, 0.0))
        return (sector + 1) % n, y, max(-x, 0.0), xk2, yk2
    if y < -tol and x >= -tol:         # sector - 1: x' = -y, y' = x
        xk2, yk2 = map_knots(np.asarray(xk), np.asarray(yk), (1, 0.0, 0.0))
        return (sector - 1) % n, -y, max(x, 0.0), xk2, yk2
    if abs(x) <= tol and abs(y) <= tol:
        return None                    # S itself
    return None                        # behind S: not a node of this chart's neighbourhood


def children(n: int, f: Fn, own_chart: bool = False, behind_rows=None):
    """The 25 children of ``f`` (midpoint refinement), canonicalised; those at S or behind
    it are left out (S's new point is the vertex rule). ``own_chart``: keep only children in
    ``f``'s own sector (S is split once per sector chart).

    ``behind_rows`` (b_j, d_(j+2), d_(j-2)) for ``f``'s sector: a function on spoke j (S, the
    spoke vertex and the spoke points of every level) reaches behind S along the spoke,
    where no single knot frame exists. Its children on the spoke keep the spoke's interval
    b_j; those on the rows through the neighbouring spokes' vertices (y > 0 and y < 0) cross
    S's neighbouring spokes at regular vertices, where the T-mesh gives the interval behind
    as d_(j+2) and d_(j-2) (the faces of sectors j+1 and j-1 there): they are split from the
    function with that interval in place of b_j, so that every child is the refined T-mesh's
    own B-spline (ray cast on the level below) with the knot-insertion coefficient of the
    NURCC rules. With b_j = d_(j+2) = d_(j-2) (valence 4, uniform stars) this is plain
    knot insertion."""
    kx, cx_ = split(f.xk)
    ky, cy_ = split(f.yk)
    rows_x = None
    tol = 1e-12 * float(f.xk[-1] - f.xk[0])
    if behind_rows is not None and abs(f.cy) <= tol and f.xk[0] < -tol:
        b, up, down = behind_rows
        neg = np.asarray(f.xk) < -tol
        rows_x = {}
        for sign, beh in ((1, up), (-1, down)):
            xk = np.where(neg, np.asarray(f.xk) * (beh / b), f.xk)
            rows_x[sign] = split(xk)
    out = []
    for b_ in range(len(cy_)):
        if cy_[b_] == 0.0:
            continue
        yc = ky[b_][2]
        kxx, cxx = kx, cx_
        if rows_x is not None and abs(yc) > tol:
            kxx, cxx = rows_x[1 if yc > 0.0 else -1]
        for a in range(len(cxx)):
            if cxx[a] == 0.0:
                continue
            xk, yk = kxx[a], ky[b_]
            c = _canon(n, f.sector, xk[2], yk[2], xk, yk)
            if c is None or (own_chart and c[0] != f.sector):
                continue
            s, x, y, xk, yk = c
            out.append(Fn(s, x, y, np.asarray(xk, float), np.asarray(yk, float), f.row * (cxx[a] * cy_[b_])))
    return out


# -- one star -------------------------------------------------------------------------------
@dataclass
class StarZone:
    """One star point: its sectors, the W0 functions, the subdivision and the functions to
    add directly on every face of its two rings."""
    v: int
    n: int
    faces: list            # F_j
    spokes: list           # s_j
    diags: list            # q_j
    d: np.ndarray          # spoke intervals d_j
    b: np.ndarray          # intervals behind S along spoke j
    chart: dict            # zone face -> (sector, map face frame -> sector chart)
    ring1: set = field(default_factory=set)
    direct: list = field(default_factory=list)        # Fn, plain B-splines (D1, D2, W1 on ring 2)
    w1: list = field(default_factory=list)            # W1 functions (evaluated directly on ring 2)
    extra: list = field(default_factory=list)         # T-junctions on the first faces' outer sides

    def behind_rows(self, j: int):
        """Intervals behind S along spoke j: on the spoke, and on the rows through the
        neighbouring spokes' vertices (``children``)."""
        n = self.n
        return float(self.b[j]), float(self.d[(j + 2) % n]), float(self.d[(j - 2) % n])

    @property
    def w0(self) -> list:
        return [self.v] + list(self.spokes) + list(self.diags) + list(self.extra)

    # -- nodes near S at level k: S, E_j (spoke j), F_j (face j) ---------------------------------
    def w_index(self, sector, x, y, level, tol) -> int | None:
        h = 0.5 ** level
        if abs(x - h * self.d[sector]) <= tol and abs(y) <= tol:
            return 1 + sector
        if abs(x - h * self.d[sector]) <= tol and abs(y - h * self.d[(sector + 1) % self.n]) <= tol:
            return 1 + self.n + sector
        return None

    def w_knots(self, node: int, level: int, beyond=None):
        """Knots of W_k node ``node`` (1..n spoke points, n+1..2n face points) in its chart:
        the level-k mesh's, scaled spoke intervals. At level 1 the outermost knots lie in the
        second ring of faces: ``beyond`` = (e, gx, gy), the T-mesh's intervals beyond the
        spoke vertices and beyond the diagonal vertices along x and y, halved there."""
        n, d, b = self.n, self.d, self.b
        h = 0.5 ** level
        j = (node - 1) % n
        dj, dn, dp, dnn = d[j], d[(j + 1) % n], d[(j - 1) % n], d[(j + 2) % n]
        x3, y3 = 3 * h * dj, 3 * h * dn
        if beyond is not None:
            e, gx, gy = beyond
            x3 = dj + (e[j] if node <= n else gx[j]) / 2
            y3 = dn + gy[j] / 2
        if node <= n:                                  # spoke point (h dj, 0)
            xk = np.array([-h * b[j], 0.0, h * dj, 2 * h * dj, x3])
            yk = h * np.array([-2 * dp, -dp, 0.0, dn, 2 * dn])
        else:                                          # face point (h dj, h dn)
            xk = np.array([-h * dnn, 0.0, h * dj, 2 * h * dj, x3])
            yk = np.array([-h * dp, 0.0, h * dn, 2 * h * dn, y3])
        return j, xk, yk

    def s_knots(self, sector: int, level: int):
        n, d, b = self.n, self.d, self.b
        h = 0.5 ** level
        j = sector
        return (h * np.array([-2 * b[j], -b[j], 0.0, d[j], 2 * d[j]]),
                h * np.array([-2 * d[(j - 1) % n], -d[(j - 1) % n], 0.0, d[(j + 1) % n], 2 * d[(j + 1) % n]]))

    def point_rules(self, rows: np.ndarray, e, gx, gy, uniform: bool = False) -> np.ndarray:
        """The next level's S, spoke and face points from this level's (``rows``: S, s_j,
        q_j, any trailing columns), by the NURCC rules (Sederberg et al. 1998; affine, and
        exact knot insertion wherever the knots are a tensor grid). ``e[j]``: the interval
        beyond s_j along spoke j; ``gx[j]``, ``gy[j]``: beyond q_j along x and y of sector j.
        ``uniform``: every interval equal (Catmull-Clark's rules)."""
        n, d, b = self.n, self.d, self.b
        if uniform:
            d = b = e = gx = gy = np.ones(n)
        S, sp, fq = rows[0], rows[1:1 + n], rows[1 + n:1 + 2 * n]
        new = np.zeros_like(rows[:2 * n + 1])
        M = []
        for i in range(n):
            di, dn = d[i], d[(i + 1) % n]
            # face point: each corner weighted by the intervals beyond the far corners
            wl = di + e[i] + gx[i]                     # corners at x = 0 (S, s_(i+1))
            wr = di + b[i] + d[(i + 2) % n]            # corners at x = d_i (s_i, q_i)
            wb = dn + e[(i + 1) % n] + gy[i]           # corners at y = 0 (S, s_i)
            wt = dn + b[(i + 1) % n] + d[(i - 1) % n]  # corners at y = d_(i+1) (s_(i+1), q_i)
            new[1 + n + i] = (wl * wb * S + wr * wb * sp[i] + wr * wt * fq[i] + wl * wt * sp[(i + 1) % n]) / (
                (wl + wr) * (wb + wt))
            M.append(((di + 2 * e[i]) * S + (di + 2 * b[i]) * sp[i]) / (2 * (b[i] + di + e[i])))
        F = new[1 + n:]
        total = 0.0
        acc = np.zeros_like(S)
        for i in range(n):
            up, down = d[(i + 1) % n], d[(i - 1) % n]
            new[1 + i] = 0.5 * M[i] + (down * F[i] + up * F[(i - 1) % n]) / (2 * (up + down))
            m = 0.5 * (d[(i - 1) % n] + d[(i + 1) % n]) * (d[(i - 2) % n] + d[(i + 2) % n])
            f = d[(i - 1) % n] * d[(i + 2) % n]
            acc += m * M[i] + f * F[i]
            total += m + f
        new[0] = (n - 3.0) / n * S + 3.0 / (n * total) * acc
        return new

    def step(self, level: int, rows: np.ndarray, fns: list, e, gx, gy):
        """One refinement of the W_level functions ``fns`` (their coefficient ``rows``: S,
        spoke points, face points): the next level's W rows (the NURCC point rules) and the
        other children (plain B-splines, exact). Children at the new W nodes are dropped:
        those functions stay inside the two rings of faces, where the rules define them."""
        n = self.n
        tol = 1e-9 * float(self.d.max()) * 0.5 ** level
        plain = []
        for f in fns:
            for c in children(n, f, own_chart=(f.cx == 0.0 and f.cy == 0.0), behind_rows=self.behind_rows(f.sector)):
                if self.w_index(c.sector, c.cx, c.cy, level + 1, tol) is None:
                    plain.append(c)
        return self.point_rules(rows, e, gx, gy), plain

    def self_similar(self):
        """The beyond-intervals of every level >= 1 (e, gx, gy), in level-0 units."""
        d = self.d
        return d, d.copy(), np.roll(d, -1)

    def level_fns(self, rows: np.ndarray, level: int, beyond=None) -> list:
        """W_level as Fn objects (S in every sector's chart, for its children there)."""
        out = []
        for j in range(self.n):
            xk, yk = self.s_knots(j, level)
            out.append(Fn(j, 0.0, 0.0, xk, yk, rows[0]))
        for node in range(1, 2 * self.n + 1):
            j, xk, yk = self.w_knots(node, level, beyond)
            out.append(Fn(j, xk[2], yk[2], xk, yk, rows[node]))
        return out

    # -- the stationary configuration (levels >= 2) ----------------------------------------------
    def stationary(self):
        """A (K, K): the configuration of level k+1 from level k's, k >= 2, and the
        configuration's functions at level 2 (for the patches). The configuration is W_k
        (S, spoke and face points) followed by every plain B-spline within RADIUS level-k
        intervals of S that refinement of W_k and of these produces: a function is a grid node
        of a sector with its knot vectors; near S the same node can carry several (the rows
        through S see the interval behind it, the others the next sector's), and the set
        closes because every knot scales by 1/2 per level."""
        n = self.n
        Wn = 2 * n + 1
        tol = 1e-9 * float(self.d.max()) / 8
        fns = self.level_fns(np.eye(Wn), 2)             # rows over W only, for now
        classes = {}                                    # key -> index among the plain functions
        plain = []                                      # Fn at level 2, row = its own unit later
        edges = []                                      # (parent: ("w", i) or ("y", i), child class, coefficient)

        def key_of(c):
            h = 0.125                                   # children are at level 3
            gx, gy = self.d[c.sector], self.d[(c.sector + 1) % n]
            p, q = c.cx / (h * gx), c.cy / (h * gy)
            if p > RADIUS + 1e-9 or q > RADIUS + 1e-9:
                return None
            return (c.sector, round(p, 9), round(q, 9), tuple(np.round(c.xk * 8 / gx, 9)),
                    tuple(np.round(c.yk * 8 / gy, 9)))

        def expand(parent, f, own):
            for c in children(n, f, own_chart=own, behind_rows=self.behind_rows(f.sector)):
                if self.w_index(c.sector, c.cx, c.cy, 3, tol) is not None:
                    continue
                k = key_of(c)
                if k is None:
                    continue
                if k not in classes:
                    classes[k] = len(plain)
                    # the same function one level up (knots doubled)
                    plain.append(Fn(c.sector, 2 * c.cx, 2 * c.cy, 2 * c.xk, 2 * c.yk, None))
                weight = float(c.row[np.argmax(np.abs(c.row))]) if parent[0] == "y" else None
                edges.append((parent, classes[k], c.row if parent[0] == "w" else weight))

        for f in fns:
            expand(("w", None), f, own=(f.cx == 0.0 and f.cy == 0.0))
        done = 0
        while done < len(plain):
            f = plain[done]
            expand(("y", done), Fn(f.sector, f.cx, f.cy, f.xk, f.yk, np.ones(1)), own=False)
            done += 1
        K = Wn + len(plain)
        A = np.zeros((K, K))
        A[:Wn] = self.point_rules(np.eye(K)[:Wn], *self.self_similar(), uniform=self.n != 4)
        for parent, child, coef in edges:
            if parent[0] == "w":
                A[Wn + child, :Wn] += coef
            else:
                A[Wn + child, Wn + parent[1]] += coef
        out = self.level_fns(np.eye(K)[:Wn], 2)
        for i, f in enumerate(plain):
            out.append(Fn(f.sector, f.cx, f.cy, f.xk, f.yk, np.eye(K)[Wn + i]))
        return A, out


def bezier_of(xk: np.ndarray, yk: np.ndarray, x0, x1, y0, y1) -> np.ndarray:
    """Bernstein coefficients (4, 4) [j (along y), i (along x)] of the tensor B-spline with
    knots xk, yk on the rectangle [x0, x1] x [y0, y1]."""
    from .blending import bezier_1d
    cx = bezier_1d(np.asarray(xk)[None], np.array([x0]), np.array([x1]))[0, 0]
    cy = bezier_1d(np.asarray(yk)[None], np.array([y0]), np.array([y1]))[0, 0]
    return np.outer(cy, cx)


def to_chart(n: int, f: Fn, sector: int, d: np.ndarray | None = None):
    """Knots of ``f`` in the chart of ``sector`` (the same or a neighbouring sector), or None.

    ``d`` (the spoke intervals): a function on spoke j that reaches behind the star (the
    W_k spoke points) is seen in sector j + 1 with the interval of that sector's own row
    behind it, d_(j+2), in place of b_j: there its children (``children``, rows y > 0) take
    d_(j+2), so that is the function its refinement gives there. With b_j the function would
    reach b_j / d_(j+2) level intervals into sector j + 1, onto the ring of faces where its
    level is evaluated once b_j > 2 d_(j+2), where its refinement does not: gaps and a
    broken partition of unity (measured in tests/model/test_stars.py)."""
    if f.sector == sector:
        return f.xk, f.yk
    if (f.sector + 1) % n == sector:
        xk = f.xk
        if d is not None and f.cy == 0.0 and f.cx > 0.0 and xk[0] < 0.0:
            j = f.sector
            xk = np.where(xk < 0.0, xk * (float(d[(j + 2) % n]) / float(behind(d)[j])), xk)
        return map_knots(xk, f.yk, (3, 0.0, 0.0))
    if (f.sector - 1) % n == sector:
        return map_knots(f.xk, f.yk, (1, 0.0, 0.0))
    return None


def overlaps(xk, yk, rect, tol) -> bool:
    x0, x1, y0, y1 = rect
    return xk[0] < x1 - tol and xk[-1] > x0 + tol and yk[0] < y1 - tol and yk[-1] > y0 + tol


# -- stars of a T-mesh --------------------------------------------------------------------------
class StarsTooClose(InputError):
    """Star points closer than the construction takes (less than three edges apart)."""


def _too_close(mesh, message: str, **where) -> StarsTooClose:
    exc = mesh.error(message, **where)
    return StarsTooClose(exc.message, path=exc.path, line=exc.line, item=exc.item)


def find_stars(walker: Walker, extra=()) -> dict:
    """Every star point of the T-mesh: vertex -> (faces F_j, spokes s_j, diagonals q_j, d_j),
    refusing what the construction cannot take (named). ``extra``: interior regular vertices
    to treat as stars of valence 4 as well (where the construction must give the T-spline's
    own B-splines: a check of it)."""
    mesh, topo = walker.mesh, walker.topo
    out = {}
    for v in range(mesh.n_vertices):
        if not topo.is_extraordinary(v) and v not in extra:
            continue
        name = mesh.vertex_name(v)
        if topo.boundary[v]:
            raise mesh.error(f"{name} is a star point on the boundary ({topo.total[v]} quarter turns of "
                             f"faces): not supported in T-spline models (save it as a Catmull-Clark cage, "
                             f"or split the faces)", vertex=v)
        if any(topo.span(f, i) != 1 for f, i in topo.fan[v]):
            raise mesh.error(f"{name} is a T-junction whose faces do not make a full turn: "
                             f"extraordinary points must be corners of all their faces", vertex=v)
        n = int(topo.total[v])
        if n < 3:
            raise mesh.error(f"{name} is an interior vertex with only {n} faces", vertex=v)
        faces, spokes, diags, d = [], [], [], []
        for f, i in topo.fan[v]:
            loop = [int(x) for x in mesh.faces[f]]
            if len(loop) != 4:
                spoke, diag = _ring1_corners(walker, v, f, i)
                faces.append(f)
                spokes.append(spoke)
                diags.append(diag)
                d.append(topo.length(v, spoke).real)
                continue
            faces.append(f)
            spokes.append(loop[(i + 1) % 4])
            diags.append(loop[(i + 2) % 4])
            d.append(topo.length(v, loop[(i + 1) % 4]).real)
        if min(d) <= walker.tol:
            raise mesh.error(f"a knot interval at extraordinary {name} is zero: star points need "
                             f"positive intervals on their spokes", vertex=v)
        out[v] = (faces, spokes, diags, np.array(d))
    seen = {}
    for v, (faces, spokes, diags, _) in out.items():
        for f in faces:
            if f in seen:
                raise _too_close(mesh, f"{mesh.face_name(f)} has two extraordinary corners "
                                 f"({mesh.vertex_name(seen[f])} and {mesh.vertex_name(v)}): refine the "
                                 f"T-mesh so that they are further apart", face=f)
            seen[f] = v
    for v, (faces, spokes, diags, _) in out.items():
        name = mesh.vertex_name(v)
        for w in set(spokes) | set(diags):
            if topo.boundary[w] or topo.total[w] != 4:
                close = topo.is_extraordinary(w) and not topo.boundary[w]
                kind = "extraordinary" if close else "on the boundary"
                message = (f"{mesh.vertex_name(w)} next to extraordinary {name} is {kind}: the faces "
                           f"around a star point must be surrounded by interior four-valent vertices "
                           f"(T-junctions allowed; the star points are too close, or the star is too near "
                           f"the boundary: refine the T-mesh)")
                raise _too_close(mesh, message, vertex=w) if close else mesh.error(message, vertex=w)
    owner = {}
    for v, (faces, spokes, diags, _) in out.items():
        for w in [v] + spokes + diags:
            if w in owner and owner[w] != v:
                raise _too_close(mesh, f"extraordinary {mesh.vertex_name(owner[w])} and {mesh.vertex_name(v)} share "
                                 f"the neighbour {mesh.vertex_name(w)}: star points must be at least three "
                                 f"edges apart (refine the T-mesh)", vertex=w)
            owner[w] = v
    return out


def _ring1_corners(walker: Walker, v: int, f: int, i: int) -> tuple[int, int]:
    """Spoke and diagonal corners of face f (loop position i at star v) when f has T-junctions:
    they must lie on its two sides away from the star (any number per side), where the refined
    star takes them (``tj_level``); refused by name otherwise."""
    mesh, topo = walker.mesh, walker.topo
    loop = [int(x) for x in mesh.faces[f]]
    m = len(loop)
    cs = list(mesh.corners[f])
    side = topo.side[f]
    k0 = cs.index(i)
    name = mesh.vertex_name(v)
    for p in range(m):
        if p in cs:
            continue
        k = int(side[p])
        if k in (k0, (k0 + 3) % 4):
            raise mesh.error(f"{mesh.vertex_name(loop[p])} is a T-junction on {mesh.face_name(f)} next to "
                             f"extraordinary {name}, on a side at the star (one of its spokes): the spokes "
                             f"of a star point must run to its first faces' corners", vertex=loop[p])
        a, b = topo.pos[f][cs[k]], topo.pos[f][cs[(k + 1) % 4]]
        length = abs(complex(b[0] - a[0]).real) + abs(complex(b[1] - a[1]).real)
        along = abs(complex(topo.pos[f][p][0] - a[0]).real) + abs(complex(topo.pos[f][p][1] - a[1]).real)
        # the fraction of the side from its corner on a spoke (the star's row)
        r = along / length if length > 0 else 0.5
        r = r if k == (k0 + 1) % 4 else 1.0 - r
        if tj_level(r) is None:
            raise mesh.error(f"{mesh.vertex_name(loop[p])} is a T-junction on {mesh.face_name(f)} next to "
                             f"extraordinary {name} at {r:.6g} of its side from the spoke (in knot space): "
                             f"the first faces around a star point take a T-junction on an outer side only "
                             f"at 3/{2 ** MAX_TJ_LEVEL} of it or further from the spoke, or at k/"
                             f"{2 ** MAX_TJ_LEVEL} (knots of the star refined {MAX_TJ_LEVEL} times); split "
                             f"the faces there or move the T-junction one face further out", vertex=loop[p])
    return loop[cs[(k0 + 1) % 4]], loop[cs[(k0 + 2) % 4]]


def tj_level(r: float) -> int | None:
    """The level m (1 .. MAX_TJ_LEVEL) of the refined star that takes a first face's T-junction
    at the fraction r in (0, 1) of its side from the spoke (``_levelm_parts``): the first at
    which r is a knot of the star's grid (r = k / 2^m) or lies at least three level-m intervals
    from the spoke (3 / 2^m <= r: the pieces of the level-m refinement around the star then
    have none of its knots), or None."""
    for m in range(1, MAX_TJ_LEVEL + 1):
        k = r * 2 ** m
        if (abs(k - round(k)) <= 1e-9 * 2 ** m and 0 < round(k) < 2 ** m) or k >= 3.0 - 1e-9:
            return m
    return None


def ring1_t_junctions(walker: Walker, v: int, faces: list, charts: dict) -> list:
    """The T-junctions on the outer sides of star v's first faces: [(vertex, sector, x, y)]
    with (x, y) in the sector's chart ((d_j, y) or (x, d_(j+1)))."""
    mesh, topo = walker.mesh, walker.topo
    out = []
    for j, f in enumerate(faces):
        loop = [int(x) for x in mesh.faces[f]]
        if len(loop) == 4:
            continue
        m = charts[f][1]
        for p in range(len(loop)):
            if p in mesh.corners[f]:
                continue
            x, y = apply(m, *topo.pos[f][p])
            out.append((loop[p], j, complex(x).real, complex(y).real))
    return out


def behind(d: np.ndarray) -> np.ndarray:
    """The interval behind a star point along each spoke: the mean of the spokes two steps
    away on either side (the opposite spoke at valence 4). It serves the rules and the
    functions on the spoke itself; off the spoke the T-mesh's own intervals apply
    (``StarZone.behind_rows``)."""
    n = len(d)
    return np.array([0.5 * (d[(j + 2) % n] + d[(j - 2) % n]) for j in range(n)])


def _vertex_to_chart(walker: Walker, A: int, f: int, chart_map):
    """The map from vertex A's own frame (the one its local knots are in) to the chart in
    which face f has ``chart_map``."""
    topo = walker.topo
    loop = [int(x) for x in walker.mesh.faces[f]]
    i = loop.index(A)
    a = topo.fan_position[(f, i)]
    q = (a - topo.out_dir(f, i)) % 4
    px, py = rot(q, *topo.pos[f][i])
    to_vertex = (q, -px, -py)
    m = compose(chart_map, inverse(to_vertex))
    return (m[0], complex(m[1]).real, complex(m[2]).real)


def build_zone(walker: Walker, v: int, star, knots, Pw: np.ndarray) -> StarZone:
    """The construction for star v: charts of its two rings of faces, the W0 functions with
    their T-spline knots (knot ``behind`` the star along its spokes), the subdivision of
    levels 0 -> 1 -> 2 (plain children kept as functions of their own) and the
    stationary configuration beyond."""
    mesh, topo = walker.mesh, walker.topo
    faces, spokes, diags, d = star
    n = len(faces)
    b = behind(d)
    chart = {}
    for j, f in enumerate(faces):
        i = [int(x) for x in mesh.faces[f]].index(v)
        q = (-topo.out_dir(f, i)) % 4
        px, py = rot(q, *topo.pos[f][i])
        chart[f] = (j, (q, -complex(px).real, -complex(py).real))
    zone = StarZone(v, n, list(faces), list(spokes), list(diags), d, b, chart, set(faces))
    # the second ring, each face in its sector's chart (reached across edges not at the star)
    members = {g for w in spokes + diags for g, _ in topo.fan[w]}
    tol = 1e-9 * max(d)

    def flood(keep, spokes_cut=False):
        """Faces reached across edges not at the star, within sector j, that ``keep(h, j,
        rect)`` takes, added to ``chart``. ``spokes_cut``: a face of the second ring across
        spoke j (where the spoke's line ends at a T-junction s_j) goes to sector j, whose
        chart holds the faces on both sides of the spoke."""
        for j in range(n):
            stack = [g for g, (jj, _) in chart.items() if jj == j]
            while stack:
                g = stack.pop()
                mg = chart[g][1]
                loop = mesh.faces[g]
                for k in range(len(loop)):
                    if v in (int(loop[k]), int(loop[(k + 1) % len(loop)])):
                        continue
                    hit = walker.cross_map(g, k)
                    if hit is None or hit[0] in chart:
                        continue
                    h, m_hg = hit
                    m = compose(mg, m_hg)
                    m = (m[0], complex(m[1]).real, complex(m[2]).real)
                    rect = tuple(complex(c).real for c in walker.face_rect(h, m))
                    across = spokes_cut and rect[2] < -tol < rect[3] and rect[0] > tol
                    if rect[0] >= -tol and (rect[2] >= -tol or across) and keep(h, j, rect):    # in sector j
                        chart[h] = (j, m)
                        stack.append(h)

    flood(lambda h, j, rect: h in members, spokes_cut=True)
    missing = members - set(chart)
    if missing:
        g = min(missing)
        raise mesh.error(f"{mesh.face_name(g)} next to extraordinary {mesh.vertex_name(v)} does not fit "
                         f"the star's sectors", g)
    # W0: the star in every sector's chart, s_j and q_j in sector j's, their T-spline knots
    ring1 = ring1_t_junctions(walker, v, faces, chart)
    zone.extra = [t[0] for t in ring1]
    W = 2 * n + 1
    eye = np.eye(W + len(ring1))
    fns, e, gx, gy = [], np.zeros(n), np.zeros(n), np.zeros(n)
    for j in range(n):
        m = chart[faces[j]][1]
        sx, sy = (np.asarray(k).real for k in knots.in_frame(spokes[j], inverse(_vertex_to_chart(
            walker, spokes[j], faces[j], m))))
        qx, qy = (np.asarray(k).real for k in knots.in_frame(diags[j], inverse(_vertex_to_chart(
            walker, diags[j], faces[j], m))))
        sx = sx.copy()
        sx[0] = -b[j]                                   # the ray through the star
        e[j] = sx[3] - sx[2]
        gx[j] = qx[3] - qx[2]
        gy[j] = qy[3] - qy[2]
        fns.append(Fn(j, d[j], 0.0, sx, sy, eye[1 + j]))
        fns.append(Fn(j, d[j], d[(j + 1) % n], qx, qy, eye[1 + n + j]))
    try:
        corrections = _ring1_functions(walker, zone, knots, ring1, fns, e, gx, gy, eye) if ring1 else []
    except Uncleared as exc:
        raise mesh.error(f"T-junctions on the first faces around extraordinary {mesh.vertex_name(v)} that "
                         f"the refinement cannot take ({exc}); split the faces between them or move one "
                         f"of them one face further out", vertex=v) from None
    # T-junctions in the second ring cut the knot lines beyond the star's neighbours: clear
    # them by knot insertion first (the W1 functions need one knot vector each)
    for j in range(n):
        beyond = (e[j], gx[j], gy[(j - 1) % n])
        if min(beyond) <= tol < max(beyond):
            raise mesh.error(f"a T-junction within two rings of faces of extraordinary {mesh.vertex_name(v)} "
                             f"(beyond {mesh.vertex_name(spokes[j])}: the knot intervals next along spoke "
                             f"{j} and its two neighbours are {', '.join(f'{x:g}' for x in beyond)}): a zero "
                             f"interval there cannot be extended across the star's second ring; move the "
                             f"T-junction one face further out", vertex=spokes[j])
    try:
        rows, fns, extra = clear_t_junctions(zone, fns, e, gx, gy, eye.shape[1])
    except Uncleared as exc:
        raise mesh.error(f"T-junctions within two rings of faces of extraordinary {mesh.vertex_name(v)} "
                         f"that local knot insertion cannot clear ({exc}); move them one face further "
                         f"out", vertex=v) from None
    # where a T-junction cut a knot line, the star's function and the pieces of its
    # neighbours' that see the interval behind the star reach beyond the second ring (up to
    # the farthest of the three knots beyond each spoke): those faces join the zone, where
    # the refined functions replace them
    reach = d + np.maximum(np.maximum(e, gx), np.roll(gy, 1))
    flood(lambda h, j, rect: rect[0] < reach[j] - tol and rect[2] < reach[(j + 1) % n] - tol)
    e = gx = np.array([min(e[j], gx[j], gy[(j - 1) % n]) for j in range(n)])
    gy = np.roll(e, -1)
    for j in range(n):
        xk = np.array([-2 * b[j], -b[j], 0.0, d[j], d[j] + e[j]])
        yk = np.array([-(d[(j - 1) % n] + e[(j - 1) % n]), -d[(j - 1) % n], 0.0, d[(j + 1) % n],
                       d[(j + 1) % n] + e[(j + 1) % n]])
        fns.append(Fn(j, 0.0, 0.0, xk, yk, rows[0]))
    rows1, plain1 = zone.step(0, rows, fns, e, gx, gy)
    # the level of the refined star on whose grid every T-junction along spoke k lies
    # the level of the refined star for the first faces' T-junctions: level 1 (``_level1_parts``)
    # where they all sit at their sides' middles; else the first level that takes them all
    # (``tj_level``, at least 2: ``_levelm_parts``)
    on_spoke, in_face, faces_on = {}, {}, {}
    for _, j, x, y in ring1:
        k = j if abs(x - d[j]) <= tol else (j + 1) % n
        m = tj_level(y / d[(j + 1) % n] if k == j else x / d[j])
        on_spoke[k] = max(on_spoke.get(k, 1), m)
        in_face[j] = max(in_face.get(j, 2), m)
        faces_on.setdefault(k, set()).add(j)
    level1 = all(m == 1 for m in on_spoke.values())
    # T-junctions on both faces at one spoke (off the level-1 path): their changes are taken one
    # face after the other (``_two_faced``), each step the change its face's T-junctions make
    # to the layout with those of the faces before; the faces in index order, the order in
    # which every function's changes are taken (measured: the other order at spoke 1 misses
    # the partition of unity by 1e-2 at valences 3 to 6)
    two = {k: sorted(fs) for k, fs in faces_on.items() if len(fs) > 1 and not level1}
    # a step's functions may hold the knots of the T-junctions of earlier steps: every step
    # off the level-1 path takes the deepest level
    top = max(in_face.values(), default=2)
    steps = []                             # (function, spoke, level, face)
    try:
        for f, spoke, virtual, sides in corrections:
            if level1:
                steps.append((f, spoke, 1, None))
                continue
            if sides is None:
                continue                       # a virtual function: in its actual one's steps
            if virtual is None:                # a T-junction's own function
                face = sides[0][3]
                m = 1 if on_spoke[spoke] == 1 else top
                if spoke in two and face == two[spoke][0]:
                    # in the first face's step as the layout without the second face's T-junctions
                    g = _two_faced(zone, f, spoke, ring1, two[spoke][:1], None, corrections, tol)
                    steps.append((g, spoke, m, face))
                    steps.append((Fn(f.sector, f.cx, f.cy, f.xk, f.yk, f.row), spoke, m, two[spoke][1]))
                    steps.append((Fn(g.sector, g.cx, g.cy, g.xk, g.yk, -g.row), spoke, m, two[spoke][1]))
                    continue
                steps.append((f, spoke, 1 if on_spoke[spoke] == 1 else top, face))
                continue
            # the difference, actual minus virtual, one T-junction at a time (middle ones first):
            # each step is the change that one T-junction makes, in its own face's chart
            xk, yk = virtual.xk.copy(), virtual.yk.copy()
            order = sorted(sides, key=lambda t: (t[3] is not None and on_spoke[t[4]] != 1, t[3] or 0, t[0]))
            for axis, lo, hi, face, sp in order:
                if sp in two and face is not None and _on_line(zone, f, sp, tol) == axis:
                    # first the change of the first face's T-junctions alone, then the second's
                    g = _two_faced(zone, f, sp, ring1, two[sp][:1], virtual, corrections, tol)
                    mid = (g.xk if axis == 0 else g.yk)[lo:hi]
                    if np.abs(mid - (xk if axis == 0 else yk)[lo:hi]).max() > tol:
                        nxk, nyk = xk.copy(), yk.copy()
                        (nxk if axis == 0 else nyk)[lo:hi] = mid
                        m = 1 if on_spoke[sp] == 1 else top
                        steps.append((Fn(f.sector, f.cx, f.cy, nxk, nyk, f.row), sp, m, two[sp][0]))
                        steps.append((Fn(f.sector, f.cx, f.cy, xk, yk, -f.row), sp, m, two[sp][0]))
                        xk, yk = nxk, nyk
                    face = two[sp][1]
                    if np.abs((f.xk if axis == 0 else f.yk)[lo:hi] - (xk if axis == 0 else yk)[lo:hi]).max() <= tol:
                        continue
                nxk, nyk = xk.copy(), yk.copy()
                (nxk if axis == 0 else nyk)[lo:hi] = (f.xk if axis == 0 else f.yk)[lo:hi]
                m = 1 if face is None or on_spoke[sp] == 1 else top
                steps.append((Fn(f.sector, f.cx, f.cy, nxk, nyk, f.row), sp, m, face))
                steps.append((Fn(f.sector, f.cx, f.cy, xk, yk, -f.row), sp, m, face))
                xk, yk = nxk, nyk
    except Uncleared as exc:
        raise mesh.error(f"T-junctions on the first faces around extraordinary {mesh.vertex_name(v)} "
                         f"that the refinement cannot take ({exc}); move them one face further out",
                         vertex=v) from None
    late = {}                              # level m >= 2 -> rows added to W_m
    for f, spoke, m, face in steps:        # the first faces' T-junctions: exact differences
        try:
            if m == 1:
                w, plain = _level1_parts(zone, f, (e, gx, gy), spoke)
            else:
                w, plain = _levelm_parts(zone, f, spoke, m, face)
        except Uncleared as exc:
            raise mesh.error(f"T-junctions on the first faces around extraordinary {mesh.vertex_name(v)} "
                             f"that the refinement cannot take ({exc}); move them one face further out",
                             vertex=v) from None
        if m == 1:
            rows1 = rows1 + w
        else:
            late[m] = late.get(m, 0.0) + w
        plain1 = plain1 + plain
    # W1 as functions: their outermost knots in the second ring, where the T-mesh's are
    zone.w1 = zone.level_fns(rows1, 1, beyond=(e, gx, gy))
    rows2, plain2 = zone.step(1, rows1, zone.w1, *zone.self_similar())
    if 2 in late:
        rows2 = rows2 + late.pop(2)
    zone.late = late
    zone.d1, zone.d2 = _merge(plain1 + extra), _merge(plain2)
    zone.points = Pw[zone.w0]
    zone.rows2 = rows2
    return zone


def _on_line(zone: StarZone, f: Fn, k: int, tol: float) -> int | None:
    """The axis of f's chart along which f's centre lies on the line through spoke vertex s_k
    across spoke k (x = d_k in sector k's chart, y = d_k in sector k - 1's), or None."""
    n, d = zone.n, zone.d
    if f.sector == k and abs(f.cx - d[k]) <= tol:
        return 1
    if f.sector == (k - 1) % n and abs(f.cy - d[k]) <= tol:
        return 0
    return None


def _two_faced(zone: StarZone, f: Fn, k: int, ring1: list, faces: list, virtual, corrections: list,
               tol: float) -> Fn:
    """Function f (actual knots; ``virtual`` its knots without first-face T-junctions, or None
    for a T-junction's own function) as it is in the layout with only the T-junctions of
    ``faces`` on the line through s_k across spoke k: its two knot pairs along that line are
    the nearest crossings of the line, the T-mesh's (s_k's virtual knots, f's own) and those
    T-junctions. Checked: with all the line's T-junctions they are f's actual knots."""
    n, d = zone.n, zone.d
    axis = _on_line(zone, f, k, tol)
    if axis is None:
        return f
    sgn = 1.0 if f.sector == k else -1.0          # sector k's coordinate along the line -> f's
    sk = next((v for g, _, v, sd in corrections if v is not None and g.sector == k
               and abs(g.cx - d[k]) <= tol and abs(g.cy) <= tol), None)
    if sk is None:
        raise Uncleared(f"no ray of spoke vertex {k} along the line across spoke {k}")
    ts = {}                                          # face -> T-junction positions (f's coordinate)
    for _, j, x, y in ring1:
        if j == k and abs(x - d[k]) <= tol:
            ts.setdefault(j, []).append(sgn * y)
        elif j == (k - 1) % n and abs(y - d[k]) <= tol:
            ts.setdefault(j, []).append(-sgn * x)
    every = [u for us in ts.values() for u in us]
    own = np.asarray(f.xk if axis == 0 else f.yk, float)
    base = [sgn * u for u in sk.yk] + list(own)
    if virtual is not None:
        base += list(virtual.xk if axis == 0 else virtual.yk)
    base = [u for u in base if all(abs(u - t) > tol for t in every)]

    def knots(keep):
        pts = []
        for u in sorted(base + [t for j in keep for t in ts.get(j, [])]):
            if not pts or u - pts[-1] > tol:
                pts.append(u)
        c = own[2]
        below = [u for u in pts if u < c - tol][-2:]
        above = [u for u in pts if u > c + tol][:2]
        if len(below) < 2 or len(above) < 2:
            raise Uncleared(f"the crossings of the line across spoke {k} near a function at ({f.cx:g}, {f.cy:g})")
        return np.array(below + [c] + above)

    if np.abs(knots(list(ts)) - own).max() > 1e-9 * float(d.max()):
        raise Uncleared(f"a function at ({f.cx:g}, {f.cy:g}) whose knots along the line across spoke {k} "
                        f"are not the line's crossings")
    new = knots(faces)
    xk, yk = (new, np.asarray(f.yk, float)) if axis == 0 else (np.asarray(f.xk, float), new)
    return Fn(f.sector, f.cx, f.cy, xk, yk, f.row)


def _ring1_functions(walker: Walker, zone: StarZone, knots, ring1: list, fns: list, e, gx, gy,
                     eye: np.ndarray) -> list:
    """T-junctions on the outer sides of the star's first faces (``ring1``, at the sides'
    middles): the T-junction's own function wraps around the star (it is a W0 function), and
    it cuts the rays of the neighbours beside it (a spoke's and a diagonal's along that side,
    the next sector's diagonal beyond the spoke). The construction runs on the star without
    them: ``fns`` (s_j, q_j in order) get the knots the rays would have without the
    T-junctions (in place), and the exact difference, actual minus those, is returned as
    functions with signed rows, refined separately (``_level1_parts``: the T-junctions' knots
    are knots of the refined star, so every piece is a level-1 function of the star or a
    plain B-spline). At valence 4 the sum is the T-spline's own."""
    n, d = zone.n, zone.d
    tol = 1e-9 * float(d.max())
    out = []
    for j in range(n):
        s_f, q_f = fns[2 * j], fns[2 * j + 1]
        sy = np.array([-(d[(j - 1) % n] + gx[(j - 1) % n]), -d[(j - 1) % n], 0.0, d[(j + 1) % n],
                       d[(j + 1) % n] + gy[j]])
        qx = np.concatenate([[-d[(j + 2) % n], 0.0], q_f.xk[2:]])
        qy = np.concatenate([[-d[(j - 1) % n], 0.0], q_f.yk[2:]])
        for k, (f, xk, yk) in enumerate(((s_f, s_f.xk, sy), (q_f, qx, qy))):
            if max(np.abs(xk - f.xk).max(), np.abs(yk - f.yk).max()) <= tol:
                continue
            # a T-junction's knot behind the star's row (the spoke's own knot there, b_j, is
            # not one: no T-junction lies on a spoke)
            behind = [k == 1 and any(-d[(j + 2) % n] + tol < u < -tol for u in f.xk),
                      any(-d[(j - 1) % n] + tol < u < -tol for u in f.yk)]
            if all(behind) and n == 3:
                w = (zone.spokes if k == 0 else zone.diags)[j]
                raise Uncleared(f"the rays of {walker.mesh.vertex_name(w)}, the {'spoke' if k == 0 else 'diagonal'} "
                                f"vertex of sector {j}, meet first-face T-junctions on both sides of the star")
            virtual = Fn(f.sector, f.cx, f.cy, np.asarray(xk, float), np.asarray(yk, float), f.row)
            fns[2 * j + k] = virtual
            spoke = j if k == 0 else _cut_by(f, j, n, d, tol)
            # the rays' knot pairs that differ, each with the face (and spoke) of the T-junction
            # that cut it: (axis, first, last, face, spoke); a pair with no first-face
            # T-junction's knot (a second-ring knot) goes with the level-1 path (face None)
            sides = []
            for axis, act, vir in ((0, f.xk, virtual.xk), (1, f.yk, virtual.yk)):
                ranges = ((0.0, d[j], j, (j + 1) % n), (-d[(j + 2) % n], 0.0, (j + 1) % n, (j + 1) % n)) if axis == 0 \
                    else ((0.0, d[(j + 1) % n], j, j), (-d[(j - 1) % n], 0.0, (j - 1) % n, j))
                for lo, hi in ((0, 2), (3, 5)):
                    if np.abs(act[lo:hi] - vir[lo:hi]).max() <= tol:
                        continue
                    hits = {(face, sp) for a, b, face, sp in ranges if any(a + tol < u < b - tol for u in act[lo:hi])}
                    if len(hits) > 1:
                        raise Uncleared(f"a ray of {walker.mesh.vertex_name((zone.spokes if k == 0 else zone.diags)[j])} "
                                        f"meets T-junctions of two first faces")
                    face, sp = hits.pop() if hits else (None, (j + 1) % n if axis == 0 else j)
                    sides.append((axis, lo, hi, face, sp))
            out.append((f, spoke, virtual, sides))
            out.append((Fn(f.sector, f.cx, f.cy, virtual.xk, virtual.yk, -f.row), spoke, None, None))
    for col, (t, j, x, y) in enumerate(ring1):
        m = zone.chart[zone.faces[j]][1]
        tx, ty = (np.asarray(k).real for k in knots.in_frame(t, inverse(_vertex_to_chart(
            walker, t, zone.faces[j], m))))
        spoke = j if abs(x - d[j]) <= tol else (j + 1) % n          # along spoke j or spoke j + 1
        out.append((Fn(j, x, y, np.array(tx, float), np.array(ty, float), eye[2 * n + 1 + col]), spoke, None,
                    [(None, 0, 0, j, spoke)]))
    return out


def _cut_by(q: Fn, j: int, n: int, d: np.ndarray, tol: float) -> int:
    """The spoke along which the first-face T-junction lies that cut diagonal q_j's rays:
    spoke j (a T-junction on F_j's side along spoke j, or on F_(j-1)'s along spoke j) or
    spoke j + 1."""
    if any(tol < u < d[(j + 1) % n] - tol or -d[(j - 1) % n] + tol < u < -tol for u in q.yk):
        return j
    return (j + 1) % n


def _match_last(pk: np.ndarray, nk: np.ndarray, tol: float) -> list:
    """A piece's knots ``pk`` as the level-1 function's ``nk`` (``_onto``): the knots at and
    beyond the star's row must agree; those behind it (negative) may differ only where the
    interval behind the star is the NURCC mean (valence other than 4), and are then the
    level-1 function's."""
    if any(nk[i] >= -tol and abs(pk[i] - nk[i]) > tol for i in range(1, 4)):
        raise Uncleared(f"knots {', '.join(f'{x:g}' for x in pk)} at a level-1 point with "
                        f"{', '.join(f'{x:g}' for x in nk)}")
    if abs(pk[4] - nk[4]) <= tol:
        return []
    return _onto(np.concatenate([pk[:1], nk[1:4], pk[4:]]), nk, tol)


def _scaled_coefficient(fx_k: np.ndarray, fy_k: np.ndarray, axis: int, side: int, factor: float, a: int,
                        b_: int, keep_x: tuple, keep_y: tuple, tol: float) -> float:
    """The coefficient of piece (a, b_) of the function with knots fx_k, fy_k when its knots on
    one side of the star (``side`` -1: negative, +1: positive) along ``axis`` (0: x, 1: y)
    are scaled by ``factor`` (with the first faces' T-junction knots there)."""
    def scaled(k, keep):
        k = np.asarray(k, float)
        on = k * side > tol
        return (tuple(float(x) for x in np.where(on, k * factor, k)),
                tuple(x * factor if x * side > 0 else x for x in keep))
    kx, kpx = scaled(fx_k, keep_x) if axis == 0 else (tuple(float(x) for x in fx_k), keep_x)
    ky, kpy = scaled(fy_k, keep_y) if axis == 1 else (tuple(float(y) for y in fy_k), keep_y)
    _, cx = _split_keeping(kx, kpx, tol)
    _, cy = _split_keeping(ky, kpy, tol)
    return float(cx[a] * cy[b_])


def _level1_parts(zone: StarZone, f: Fn, beyond, spoke: int) -> tuple[np.ndarray, list]:
    """One W0 function refined to the star's level 1 (its intervals halved, except those a
    first face's T-junction already halves: ``_split_keeping``): the coefficients of its
    pieces at the level-1 points next to the star (rows (2n + 1, W0) added to the W1 rows,
    the star itself row 0) and the other pieces as plain B-splines. Pieces at a level-1 point
    whose last knot differs from the level-1 function's are split there (``_onto``). Spoke
    functions take the intervals behind the star per row as in ``children``.

    Pieces on a spoke's row (the spoke's level-1 point and the next, whose coefficients
    depend on the interval behind the star) take that interval as b_k, whatever sector the
    function is in: the functions of the two sectors beside spoke k see d_(k+2) and d_(k-2)
    there, the spoke's own b_k. The piece at the star takes b_k behind it along ``spoke``,
    the spoke k along which the T-junction that changed f lies (its functions are in the
    sectors on both sides of it). So the differences are those of one valence-4
    configuration, where they sum exactly to what the T-junctions change (the rows' sums
    stay 1: measured <= 3e-17 at valences 3 to 6); at valence 4 every interval behind is
    the same."""
    n, d = zone.n, zone.d
    j = f.sector
    bk = zone.b
    tol = 1e-9 * float(d.max())
    keep_x = (d[j] / 2, -d[(j + 2) % n] / 2)
    keep_y = (d[(j + 1) % n] / 2, -d[(j - 1) % n] / 2)
    kx, cx_ = _split_keeping(tuple(float(x) for x in f.xk), keep_x, tol)
    ky, cy_ = _split_keeping(tuple(float(y) for y in f.yk), keep_y, tol)
    rows_x = None
    ftol = 1e-12 * float(f.xk[-1] - f.xk[0])
    spoke_fn = abs(f.cy) <= ftol and f.xk[0] < -ftol
    if spoke_fn:
        b, up, down = zone.behind_rows(j)
        neg = np.asarray(f.xk) < -ftol
        rows_x = {sign: _split_keeping(tuple(float(x) for x in np.where(neg, np.asarray(f.xk) * (beh / b), f.xk)),
                                       keep_x, tol) for sign, beh in ((1, up), (-1, down))}
    w = np.zeros((2 * n + 1, len(f.row)))
    plain = []
    for b_ in range(len(cy_)):
        if cy_[b_] == 0.0:
            continue
        yk = ky[b_]
        kxx, cxx = kx, cx_
        base_x = np.asarray(f.xk, float)
        if rows_x is not None and abs(yk[2]) > ftol:
            kxx, cxx = rows_x[1 if yk[2] > 0.0 else -1]
            bj, up, down = zone.behind_rows(j)
            base_x = np.where(base_x < -ftol, base_x * ((up if yk[2] > 0.0 else down) / bj), base_x)
        for a in range(len(cxx)):
            if cxx[a] == 0.0:
                continue
            xk, coef = kxx[a], cxx[a] * cy_[b_]
            if abs(xk[2]) <= tol and abs(yk[2]) <= tol:
                node, s, txk, tyk = 0, j, *zone.s_knots(j, 1)
                cxk, cyk = xk, yk
                # the piece at the star: b behind it along the spoke of the T-junction that
                # changed f (the spoke between the sectors of the functions it changed)
                if spoke == j:
                    axis, nat = 0, (bk[j] if spoke_fn else d[(j + 2) % n])
                else:
                    axis, nat = 1, d[(j - 1) % n]
                factor = float(bk[spoke]) / float(nat)
                if abs(factor - 1.0) > 1e-15:
                    coef = _scaled_coefficient(base_x, np.asarray(f.yk, float), axis, -1, factor, a, b_,
                                               keep_x, keep_y, tol)
            else:
                c = _canon(n, j, xk[2], yk[2], xk, yk)
                if c is None:
                    raise Uncleared("a piece behind the star")
                s, x, y, cxk, cyk = c
                cxk, cyk = np.asarray(cxk, float), np.asarray(cyk, float)
                if abs(y) <= tol:                            # on spoke s's row
                    if s == j:
                        axis, side, nat = 0, -1, (bk[j] if spoke_fn and abs(yk[2]) <= ftol else d[(j + 2) % n])
                    elif s == (j + 1) % n:
                        axis, side, nat = 1, -1, d[(j - 1) % n]
                    else:
                        axis, side, nat = 1, 1, d[(j + 1) % n]
                    factor = float(bk[s]) / float(nat)
                    if abs(factor - 1.0) > 1e-15:
                        coef = _scaled_coefficient(base_x, np.asarray(f.yk, float), axis, side, factor, a, b_,
                                                   keep_x, keep_y, tol)
                node = zone.w_index(s, x, y, 1, tol)
                if node is None:
                    plain.append(Fn(s, x, y, cxk, cyk, f.row * coef))
                    continue
                _, txk, tyk = zone.w_knots(node, 1, beyond)
            w[node] += coef * f.row
            lx, ly = _match_last(cxk, txk, tol), _match_last(cyk, tyk, tol)
            terms = [(c1, kn, tyk) for c1, kn in lx] + [(c1, txk, kn) for c1, kn in ly] + \
                [(c1 * c2, k1, k2) for c1, k1 in lx for c2, k2 in ly]
            for c1, xr, yr in terms:
                r = _canon(n, s, xr[2], yr[2], xr, yr)
                if r is None:
                    raise Uncleared("a remainder piece at the star")
                plain.append(Fn(r[0], r[1], r[2], np.asarray(r[3], float), np.asarray(r[4], float),
                                f.row * (coef * c1)))
    return w, plain


@lru_cache(maxsize=None)
def _refine_grid(knots: tuple, neg: float, pos: float, m: int, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The cubic B-spline N[t0..t4] refined onto the level-m grid of a star's sector chart
    along one axis, graded: the knots i pos / 2^l (i = 1, 2, 3, l = 1 .. m) in [0, pos] (the
    first face) and -i neg / 2^l in [-neg, 0] (behind the star), so that every piece whose
    support holds the star's row has the level-m grid's knots (h, 2h, 3h and -h, -2h, -3h)
    and the pieces further out grow with their distance; each interval beyond halved.
    (children knots (k, 5), coefficients (k,)), by Boehm's insertion (exact). A piece's
    coefficient depends only on its own knots, whatever else is inserted."""
    t = [float(x) for x in knots]
    ins = []
    for a, b in zip(t[:-1], t[1:]):
        if b - a <= tol:
            continue
        if a >= -tol and b <= pos + tol:
            grid = [i * pos / 2 ** l for l in range(1, m + 1) for i in (1, 2, 3)]
        elif a >= -neg - tol and b <= tol:
            grid = [-i * neg / 2 ** l for l in range(1, m + 1) for i in (1, 2, 3)]
        else:
            grid = [(a + b) / 2]
        ins.extend(u for u in sorted(set(grid)) if a + tol < u < b - tol)
    return _boehm(t, ins)


def _boehm(t: list, ins: list) -> tuple[np.ndarray, np.ndarray]:
    """The cubic B-spline N[t0..t4] with the knots ``ins`` inserted (Boehm's insertion, one
    knot at a time in increasing order): (children knots (k, 5), coefficients (k,)), the
    refined padded vector being [t0 x3, r, t4 x3] and the children its basis functions
    3, 4, ..."""
    T = [t[0]] * 3 + t + [t[-1]] * 3
    c = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
    for u in sorted(ins):
        l = max(i for i in range(len(T) - 1) if T[i] <= u < T[i + 1])
        new = []
        for i in range(len(c) + 1):
            if i <= l - 3:
                new.append(c[i])
            elif i > l:
                new.append(c[i - 1])
            else:
                den = T[i + 3] - T[i]
                alpha = (u - T[i]) / den if den > 0 else 0.0
                new.append((1 - alpha) * c[i - 1] + alpha * c[i])
        c = new
        T = T[:l + 1] + [u] + T[l + 1:]
    r = np.sort(np.array(t + ins))
    k = len(r) - 4
    return np.array([r[i:i + 5] for i in range(k)]), np.array(c[3:3 + k])


def _frame(zone: StarZone, j: int, spoke: int, rc: int, cc: int) -> tuple[float, float, float, float]:
    """The knot intervals (behind along x, ahead along x, behind along y, ahead along y) that a
    level-m piece of a first-face T-junction's difference sees in sector j's chart, by the row
    (rc: sign of its centre's y) and column (cc: sign of its x) it is centred on: a piece on
    spoke s's row has b_s behind the star along that spoke, one off the spokes the intervals
    of the sectors its row and column cross; at the star itself b_k along the spoke k of the
    T-junction (``_level1_parts``' rules, which are these at level 1). At valence 4 every one
    is the T-mesh's own."""
    n, d, b = zone.n, zone.d, zone.b
    xm = {1: d[(j + 2) % n], 0: b[j], -1: d[(j - 2) % n]}[rc]
    ym = {1: d[(j - 1) % n], 0: b[(j + 1) % n] if rc > 0 else d[(j - 1) % n], -1: d[(j + 3) % n]}[cc]
    xp = b[(j + 2) % n] if (rc == 0 and cc < 0) else d[j]
    yp = b[(j - 1) % n] if (cc == 0 and rc < 0) else d[(j + 1) % n]
    if rc == 0 and cc == 0:
        xm = b[j] if spoke == j else d[(j + 2) % n]
        ym = b[(j + 1) % n] if spoke == (j + 1) % n else d[(j - 1) % n]
    return float(xm), float(xp), float(ym), float(yp)


def _levelm_parts(zone: StarZone, f: Fn, spoke: int, m: int, sector: int) -> tuple[np.ndarray, list]:
    """``_level1_parts`` for the T-junctions along spoke ``spoke`` whose knots lie on the
    refined star's level-m grid only (m >= 2: at k / 2^m of their sides, k odd): f refined
    onto that grid (``_refine_grid``), its pieces at the level-m points next to the star
    (rows (2n + 1, W0) added to the W_m rows) and the others as plain B-splines. Each piece
    takes its knots and coefficient from f with the intervals behind and beyond the star that
    its row and column see (``_frame``): so the pieces of all the differences at one place
    are one function and their coefficients those of one valence-4 configuration, which sum
    to what the T-junctions change (zero at the star's points and behind it). Pieces behind
    the star (in the sector opposite f's at valence 4; their coefficients sum to zero) have
    no place at other valences and are left out there."""
    n, d = zone.n, zone.d
    j = sector
    tol = 1e-9 * float(d.max())
    fx, fy = np.asarray(f.xk, float), np.asarray(f.yk, float)
    if f.sector != j:                  # a neighbouring sector's function, seen in sector j's chart
        q = 3 if f.sector == (j - 1) % n else 1
        fx, fy = (np.asarray(k, float) for k in map_knots(fx, fy, (q, 0.0, 0.0)))
    ftol = 1e-12 * float(fx[-1] - fx[0])
    sign = lambda u: 0 if abs(u) <= tol else (1 if u > 0 else -1)
    nat = _frame(zone, j, spoke, sign(fy[2]), sign(fx[2]))     # f's own intervals

    def scaled(k, neg, pos, nneg, npos):
        return tuple(float(u) for u in np.where(k < -ftol, k * (neg / nneg), np.where(k > ftol, k * (pos / npos), k)))

    w = np.zeros((2 * n + 1, len(f.row)))
    plain = []
    for rc in (1, 0, -1):
        for cc in (1, 0, -1):
            xm, xp, ym, yp = _frame(zone, j, spoke, rc, cc)
            kx, cx_ = _refine_grid(scaled(fx, xm, xp, nat[0], nat[1]), xm, xp, m, tol)
            ky, cy_ = _refine_grid(scaled(fy, ym, yp, nat[2], nat[3]), ym, yp, m, tol)
            cols = [a for a in range(len(cx_)) if cx_[a] != 0.0 and sign(kx[a][2]) == cc]
            for b_ in range(len(cy_)):
                if cy_[b_] == 0.0 or sign(ky[b_][2]) != rc:
                    continue
                yk = ky[b_]
                for a in cols:
                    xk, coef = kx[a], cx_[a] * cy_[b_]
                    if rc == 0 and cc == 0:
                        node, s, txk, tyk = 0, j, *zone.s_knots(j, m)
                        cxk, cyk = xk, yk
                    else:
                        c = _canon(n, j, xk[2], yk[2], xk, yk)
                        if c is None:
                            if n != 4:
                                continue          # behind the star (coefficients summing to zero)
                            rx, ry = map_knots(np.asarray(xk), np.asarray(yk), (2, 0.0, 0.0))
                            c = _canon(n, (j + 2) % n, rx[2], ry[2], rx, ry)
                        s, x, y, cxk, cyk = c
                        cxk, cyk = np.asarray(cxk, float), np.asarray(cyk, float)
                        node = zone.w_index(s, x, y, m, tol)
                        if node is None:
                            plain.append(Fn(s, x, y, cxk, cyk, f.row * coef))
                            continue
                        _, txk, tyk = zone.w_knots(node, m)
                    w[node] += coef * f.row
                    # the W_m function's knots: the same ahead of the star (checked), those
                    # behind it the NURCC mean's where the valence is not 4
                    if _match_last(cxk, txk, tol) or _match_last(cyk, tyk, tol):
                        raise Uncleared(f"a level-{m} piece at the star's level-{m} point {node} whose "
                                        f"last knots are not the point's")
    return w, plain


class Uncleared(Exception):
    """T-junctions next to a star that the local knot insertion cannot clear."""


def _insert(knots: np.ndarray, u: float) -> list:
    """The cubic B-spline N[t0..t4] as two B-splines of its knot vector with u inserted
    (Boehm; single-function form): [(coefficient, knots (5,)), (coefficient, knots)]."""
    t = np.asarray(knots, float)
    r = np.sort(np.append(t, u))
    return [(min(1.0, (u - t[0]) / (t[3] - t[0])), r[:5]), (min(1.0, (t[4] - u) / (t[4] - t[1])), r[1:])]


def _onto(pk: np.ndarray, nk: np.ndarray, tol: float) -> list:
    """A B-spline with knots ``pk`` as the one with knots ``nk`` (same centre, same inner
    knots) plus B-splines that do not reach behind the centre's row: [(coefficient, knots)].
    The last knots may differ (knot insertion into the one with the longer interval); the
    first knot is the interval behind the star on the row, which the T-mesh gives (the same
    in both at valence 4)."""
    if np.abs(pk[1:4] - nk[1:4]).max() > tol:
        raise Uncleared(f"knots {', '.join(f'{x:g}' for x in pk)} and {', '.join(f'{x:g}' for x in nk)} "
                        f"at the same neighbour")
    a, c = float(pk[4]), float(nk[4])
    if abs(a - c) <= tol:
        return []
    if a > c:
        return [((a - c) / (a - pk[1]), np.array([pk[1], pk[2], pk[3], c, a]))]
    return [(-(c - a) / (c - pk[1]), np.array([pk[1], pk[2], pk[3], a, c]))]


def clear_t_junctions(zone: StarZone, fns: list, e, gx, gy, columns: int | None = None):
    """Local knot insertion around a star (Sederberg et al. 2003, T-NURCCs: T-junctions near
    an extraordinary point are cleared before the NURCC refinement; the refinement of each
    blending function is exact knot insertion, Sederberg et al. 2004): the knot line beyond
    the neighbours along every spoke is extended across the star's two rings at the nearest
    of the three knots the neighbours see there (``e``, ``gx``, ``gy`` as in ``build_zone``).

    ``fns``: the spoke and diagonal vertices' functions (s_0, q_0, s_1, ...; rows over W0).
    Each is split at the extended lines its knot vectors cross: pieces centred at a star
    neighbour become (part of) that neighbour's refined function, the others are plain
    B-splines. The star's function along spoke k, knots (-b_k, 0, d_k, d_k + e_k), gives
    beta_k = (e_k - e*_k) / (d_k + e_k + b_k) of itself to s_k and, split along spoke k + 1
    as well (knots (-d_(k-1), 0, d_(k+1), d_(k+1) + e_(k+1)) in sector k's chart, as in
    ``build_zone``), beta_k (e_(k+1) - e*_(k+1)) / (d_(k+1) + e_(k+1) + d_(k-1)) to q_k.

    Returns (rows (W, W): the refined W0 functions' coefficients over the original W0
    points, the refined neighbours' functions, the plain pieces); at valence 4 the sum is
    the T-spline's own, exactly. Raises ``Uncleared`` where the pieces do not fit the
    neighbours' functions."""
    n, d, b = zone.n, zone.d, zone.b
    W = 2 * n + 1
    es = np.array([min(e[j], gx[j], gy[(j - 1) % n]) for j in range(n)])
    tol = 1e-9 * float(d.max())
    eye = np.eye(W, columns or W)
    credited = {k: [] for k in range(1, W)}
    plain = []

    def refine(f: Fn):
        j = f.sector
        lines = ([d[j] + es[j]], [d[(j + 1) % n] + es[(j + 1) % n], -(d[(j - 1) % n] + es[(j - 1) % n])])
        for axis, ks in ((0, f.xk), (1, f.yk)):
            for u in lines[axis]:
                if ks[0] + tol < u < ks[4] - tol and np.abs(ks - u).min() > tol:
                    for coef, kn in _insert(ks, u):
                        xk, yk = (kn, f.yk) if axis == 0 else (f.xk, kn)
                        c = _canon(n, j, xk[2], yk[2], xk, yk)
                        if c is None:
                            raise Uncleared("a piece of a neighbour's function at the star")
                        g = Fn(c[0], c[1], c[2], np.asarray(c[3], float), np.asarray(c[4], float), f.row * coef)
                        if zone.w_index(g.sector, g.cx, g.cy, 0, tol) is None:
                            plain.append(g)
                        else:
                            refine(g)
                    return
        credited[zone.w_index(f.sector, f.cx, f.cy, 0, tol)].append(f)

    own = {}
    for f in fns:
        k = zone.w_index(f.sector, f.cx, f.cy, 0, tol)
        own[k] = f
        refine(f)
    # the star's function along each spoke
    beta = (e - es) / (d + e + b)
    for k in range(n):
        k1, km = (k + 1) % n, (k - 1) % n
        if beta[k] > 0.0:
            xk = np.array([-b[k], 0.0, d[k], d[k] + es[k], d[k] + e[k]])
            yk = np.array([-(d[km] + es[km]), -d[km], 0.0, d[k1], d[k1] + es[k1]])
            credited[1 + k].append(Fn(k, d[k], 0.0, xk, yk, beta[k] * eye[0]))
        # the corner: the star's function in sector k's chart is the tensor B-spline with
        # knots (-b_k, 0, d_k, d_k + e_k) along x and (-d_(k-1), 0, d_(k+1), ...) along y
        corner = beta[k] * (e[k1] - es[k1]) / (d[k1] + e[k1] + d[km])
        if corner > 0.0:
            q = own[1 + n + k]
            xk = np.array([q.xk[0], 0.0, d[k], d[k] + es[k], d[k] + e[k]])
            yk = np.array([q.yk[0], 0.0, d[k1], d[k1] + es[k1], d[k1] + e[k1]])
            credited[1 + n + k].append(Fn(k, d[k], d[k1], xk, yk, corner * eye[0]))
    rows = eye.copy()
    out = []
    for k in range(1, W):
        pieces = credited[k]
        ref = max(pieces, key=lambda f: abs(f.row[k]))
        rows[k] = 0.0
        for f in pieces:
            rows[k] += f.row
            if f is ref:
                continue
            lx, ly = _onto(f.xk, ref.xk, tol), _onto(f.yk, ref.yk, tol)
            terms = [(c, kn, ref.yk) for c, kn in lx] + [(c, ref.xk, kn) for c, kn in ly] + \
                [(cx * cy, kx, ky) for cx, kx in lx for cy, ky in ly]
            for coef, xk, yk in terms:
                c = _canon(n, f.sector, xk[2], yk[2], xk, yk)
                plain.append(Fn(c[0], c[1], c[2], np.asarray(c[3], float), np.asarray(c[4], float), f.row * coef))
        out.append(Fn(ref.sector, ref.cx, ref.cy, ref.xk, ref.yk, rows[k]))
    return rows, out, plain


def _merge(fns: list) -> list:
    """Children with the same knots (the same function) summed into one."""
    out = {}
    for f in fns:
        key = (f.sector, tuple(np.round(f.xk, 12)), tuple(np.round(f.yk, 12)))
        if key in out:
            out[key].row = out[key].row + f.row
        else:
            out[key] = Fn(f.sector, f.cx, f.cy, f.xk, f.yk, f.row.copy())
    return list(out.values())


def direct_functions(zone: StarZone, walker: Walker) -> dict:
    """Per face of the star's two rings, the plain B-splines the construction adds there:
    [(homogeneous point (4,), knots along the face's x, along its y)] in the face's own frame.
    First ring: the children split off at levels 1 and 2; second ring: those of level 1 and
    the level-1 functions next to the star (which are plain B-splines there)."""
    out = {}
    tol = 1e-9 * float(zone.d.max())
    for g, (j, m) in zone.chart.items():
        rect = tuple(complex(c).real for c in walker.face_rect(g, m))
        cands = zone.d1 + (zone.d2 if g in zone.ring1 else zone.w1)
        back = inverse(m)
        rows = []
        for f in cands:
            if f.cx == 0.0 and f.cy == 0.0 and f.sector != j:
                continue                    # the star's own function lives in each sector's chart
            k = to_chart(zone.n, f, j, zone.d)
            if k is None or not overlaps(k[0], k[1], rect, tol):
                continue
            xk, yk = map_knots(np.asarray(k[0]), np.asarray(k[1]), back)
            rows.append((f.row @ zone.points, np.asarray(xk).real, np.asarray(yk).real))
        out[g] = rows
    return out


@dataclass
class _Pieces:
    """What a star's subdivided part needs besides its points (the same for every star with
    the same valence and spoke intervals, up to scale): the stationary matrix A, the
    configuration's share of the limit point ``xinf``, the tangent masks, and the Bezier
    matrices Z (cells, 16, K) of the level-2 functions on the ring faces of every sector."""
    A: np.ndarray
    xinf: np.ndarray
    masks: tuple
    spectrum: np.ndarray
    face_index: dict
    breaks: dict
    first_cell: dict
    Z: np.ndarray
    Zinf: np.ndarray


#: the pieces of stars built in this process, by valence and spoke intervals' exact bits: a
#: star whose intervals differ from a cached one in the last bit gets its own (a model's
#: values must not depend on which models the process read before)
_PIECES: dict = {}


def _pieces(zone: StarZone) -> _Pieces:
    n = zone.n
    key = (n, np.ascontiguousarray(zone.d, float).tobytes())
    hit = _PIECES.get(key)
    if hit is not None:
        return hit
    from .blending import bezier_1d
    from .eigen import _tangent_masks
    A, fns = zone.stationary()
    K = A.shape[0]
    Wn = 2 * n + 1
    xinf = np.ones(K)
    xinf[Wn:] = np.linalg.solve(np.eye(K - Wn) - A[Wn:, Wn:], A[Wn:, :Wn] @ np.ones(Wn))
    AW = A[:Wn, :Wn]
    masks = tuple(_tangent_masks(AW, f"extraordinary {zone.v}"))
    spectrum = np.sort(np.abs(np.linalg.eigvals(AW)))[::-1]
    # Bezier matrices of the level-2 functions on the ring faces of every sector, each face
    # cut at the knot lines of the functions on it (those of functions next to the star fall
    # between the grid lines where the spokes' intervals differ)
    faces = [(p, q) for p in range(4) for q in range(4) if p >= 2 or q >= 2]
    face_index = {pq: k for k, pq in enumerate(faces)}
    tol = 1e-12 * float(zone.d.max())
    breaks, first_cell, Zc = {}, {}, []
    ncells = 0
    for j in range(n):
        hx, hy = zone.d[j] / 4, zone.d[(j + 1) % n] / 4
        for k, (p, q) in enumerate(faces):
            rect = (p * hx, (p + 1) * hx, q * hy, (q + 1) * hy)
            cols, XK, YK = [], [], []
            for f in fns:
                if f.cx == 0.0 and f.cy == 0.0 and f.sector != j:
                    continue                            # the star, in another sector's chart
                kn = to_chart(n, f, j, zone.d)
                if kn is not None and overlaps(kn[0], kn[1], rect, tol):
                    cols.append(int(np.argmax(f.row)))
                    XK.append(kn[0])
                    YK.append(kn[1])
            XK, YK = np.array(XK, float).reshape(-1, 5), np.array(YK, float).reshape(-1, 5)
            xs = np.array(sorted({0.0, 1.0} | {round((x - rect[0]) / hx, 12) for x in XK.ravel()
                                                if rect[0] + tol < x < rect[1] - tol}))
            ys = np.array(sorted({0.0, 1.0} | {round((y - rect[2]) / hy, 12) for y in YK.ravel()
                                                if rect[2] + tol < y < rect[3] - tol}))
            breaks[(j, k)] = (xs, ys)
            first_cell[(j, k)] = ncells
            Cx = bezier_1d(XK, rect[0] + xs[:-1] * hx, rect[0] + xs[1:] * hx)        # (m, cx, 4)
            Cy = bezier_1d(YK, rect[2] + ys[:-1] * hy, rect[2] + ys[1:] * hy)        # (m, cy, 4)
            onehot = np.zeros((len(cols), K))
            np.add.at(onehot, (np.arange(len(cols)), cols), 1.0)
            T = np.einsum("mbj,mai,mk->bajik", Cy, Cx, onehot)   # (cy, cx, 4 [y], 4 [x], K)
            Zc.append(T.reshape(-1, 16, K))
            ncells += T.shape[0] * T.shape[1]
    Z = np.concatenate(Zc)                                       # (cells, 16, K)
    out = _Pieces(A, xinf, masks, spectrum, face_index, breaks, first_cell, Z, Z @ xinf)
    if len(_PIECES) > 64:
        _PIECES.clear()
    _PIECES[key] = out
    return out


class StarLevels:
    """The subdivided part of one star, levels 2 .. MAX_LEVEL: the configuration of every
    level (differences from its limit), the Bezier pieces of its functions on the twelve
    faces of each sector's ring [2, 4]^2 (one matrix per face: the same at every level)."""

    def __init__(self, zone: StarZone):
        n = zone.n
        self.zone = zone
        pieces = _pieces(zone)
        A, xinf = pieces.A, pieces.xinf
        K = A.shape[0]
        Wn = 2 * n + 1
        X2 = np.zeros((K, zone.points.shape[1]))
        X2[:Wn] = zone.rows2 @ zone.points
        AW = A[:Wn, :Wn]
        _, sv, vt = np.linalg.svd((AW - np.eye(Wn)).T)
        l0 = vt[-1] / vt[-1].sum()
        late = getattr(zone, "late", None)
        dm = np.empty((MAX_LEVEL + 1, K, X2.shape[1]))
        if late:
            # first-face T-junctions at k / 2^m (m >= 3): their pieces at the level-m points
            # next to the star join the configuration of that level (those of W_m reach
            # 1.5 level-(m-1) intervals from S: not the ring of level m - 1)
            top = max(late)
            Xs = {2: X2}
            for m in range(3, top + 1):
                Xs[m] = A @ Xs[m - 1]
                if m in late:
                    Xs[m][:Wn] += late[m] @ zone.points
            Xtop = Xs[top]
            self.limit = l0 @ Xtop[:Wn]
            for m in range(2, top + 1):
                dm[m] = Xs[m] - np.outer(xinf, self.limit)
            first = top + 1
        else:
            Xtop = X2
            self.limit = l0 @ X2[:Wn]                              # (4,)
            dm[2] = X2 - np.outer(xinf, self.limit)
            first = 3
        for m in range(first, MAX_LEVEL + 1):
            dm[m] = A @ dm[m - 1]
        self.d = dm
        L = self.limit
        X = L[:3] / L[3]
        t1, t2 = ((mk @ Xtop[:Wn])[:3] - X * (mk @ Xtop[:Wn])[3] for mk in pieces.masks)
        nrm = np.cross(t1, t2)
        self.normal = nrm / max(np.linalg.norm(nrm), 1e-300)
        self.spectrum = pieces.spectrum
        self.face_index, self.breaks, self.first_cell = pieces.face_index, pieces.breaks, pieces.first_cell
        self.face_lut = np.full((4, 4), -1, dtype=int)          # (p, q) of the ring -> face index
        for (pp, qq), k in self.face_index.items():
            self.face_lut[pp, qq] = k
        self.Z, self.Zinf = pieces.Z, pieces.Zinf
        self._cache_nets()

    def _cache_nets(self):
        """What a point of levels 2 .. NET_LEVEL needs, as arrays: the Bezier net of every
        face cell at every such level (``nets[cell * levels + level - 2]``, (4 [x, y, z, w],
        4 [along y], 4 [along x]): the level's differences and the limit's share beyond the
        cell's first coefficient, as ``evaluate_levels`` forms them), and per (sector, ring
        face) its cell breaks padded with +inf (``_bx``, ``_by``), first cell and cell count
        along x and y. A point is then located and evaluated without a loop over faces. The values
        at the star itself (evaluated next to it, the same for every point there) per sector:
        ``_vertex`` (6, 4, sector)."""
        n, nf = self.zone.n, len(self.face_index)
        levels = NET_LEVEL - 1
        ncell = len(self.Z)
        z0 = self.Zinf[:, :1]
        share = (self.Zinf - z0)[:, :, None] * self.limit[None, None, :]
        c = np.empty((ncell, levels, 16, self.d.shape[2]))
        for m in range(levels):
            # the products evaluate_levels forms per point, so the same rounding
            d = np.broadcast_to(self.d[m + 2], (ncell,) + self.d.shape[1:])
            c[:, m] = np.einsum("npc,ncd->npd", self.Z, d) + share
        self.nets = np.ascontiguousarray(c.reshape(ncell * levels, 4, 4, 4).transpose(0, 3, 1, 2))
        self._z0 = z0[:, 0]
        width = max(len(xs) for xs, _ in self.breaks.values()) + 1
        self._bx = np.full((n * nf, width), np.inf)
        self._by = np.full((n * nf, width), np.inf)
        self._first = np.zeros(n * nf, dtype=int)
        self._ncx = np.zeros(n * nf, dtype=int)
        self._ncy = np.zeros(n * nf, dtype=int)
        for (j, k), (xs, ys) in self.breaks.items():
            r = j * nf + k
            self._bx[r, :len(xs)] = xs
            self._by[r, :len(ys)] = ys
            self._first[r] = self.first_cell[(j, k)]
            self._ncx[r] = len(xs) - 1
            self._ncy[r] = len(ys) - 1
        sectors = np.arange(n)
        self._vertex = self.evaluate_levels(sectors, np.zeros(n), np.zeros(n))[0]

    def evaluate(self, sector: np.ndarray, x: np.ndarray, y: np.ndarray):
        """Homogeneous value and derivatives (6, 4, n) with respect to the sector chart's
        (x, y), and the points at the star itself: from the cached nets (``_cache_nets``), the
        few points below level NET_LEVEL through the level's configuration."""
        zone = self.zone
        dx = zone.d[sector]
        dy = zone.d[(sector + 1) % zone.n]
        u, w = np.maximum(x / dx, 0.0), np.maximum(y / dy, 0.0)
        mx = np.maximum(u, w)
        at_vertex = mx < 2.0 ** (2 - MAX_LEVEL)
        _, ex = np.frexp(mx)                       # mx in [2^(ex-1), 2^ex)
        level = np.minimum(np.maximum(2 - ex, 2), MAX_LEVEL)
        deep = (level > NET_LEVEL) & ~at_vertex
        level = np.minimum(level, NET_LEVEL)
        scale = np.ldexp(1.0, level)
        P, Q = u * scale, w * scale
        p = np.minimum(np.maximum(np.floor(P), 0), 3).astype(int)
        q = np.minimum(np.maximum(np.floor(Q), 0), 3).astype(int)
        inner = (p < 2) & (q < 2)
        p[inner] = 2                               # rounding at the ring's inner edge
        a = np.minimum(np.maximum(P - p, 0.0), 1.0)
        b = np.minimum(np.maximum(Q - q, 0.0), 1.0)
        # the face's cell holding the point: breaks below it, counted
        row = sector * len(self.face_index) + self.face_lut[p, q]
        bx, by = self._bx[row], self._by[row]
        nx = self._ncx[row]
        ix = np.minimum(np.count_nonzero(bx[:, 1:] <= a[:, None], axis=1), nx - 1)
        iy = np.minimum(np.count_nonzero(by[:, 1:] <= b[:, None], axis=1), self._ncy[row] - 1)
        cell = self._first[row] + iy * nx + ix
        r = np.arange(len(a))
        x0, x1, y0, y1 = bx[r, ix], bx[r, ix + 1], by[r, iy], by[r, iy + 1]
        sxw, syw = x1 - x0, y1 - y0
        a = np.minimum(np.maximum((a - x0) / sxw, 0.0), 1.0)
        b = np.minimum(np.maximum((b - y0) / syw, 0.0), 1.0)
        H = bicubic_nets(self.nets[cell * (NET_LEVEL - 1) + level - 2], a, b)
        H[0] += self._z0[cell][None, :] * self.limit[:, None]
        scale_derivatives(H, scale / (dx * sxw), scale / (dy * syw))
        if at_vertex.any():
            H[:, :, at_vertex] = self._vertex[:, :, sector[at_vertex]]
        if deep.any():
            H[:, :, deep] = self.evaluate_levels(sector[deep], x[deep], y[deep])[0]
        return H, at_vertex

    def evaluate_levels(self, sector: np.ndarray, x: np.ndarray, y: np.ndarray):
        """``evaluate`` from the configuration of every point's level: the points below
        NET_LEVEL and at the star itself, and the reference the cached nets are tested against."""
        zone = self.zone
        n = len(x)
        dx = zone.d[sector]
        dy = zone.d[(sector + 1) % zone.n]
        u, w = np.maximum(x / dx, 0.0), np.maximum(y / dy, 0.0)
        mx = np.maximum(u, w)
        at_vertex = mx < 2.0 ** (2 - MAX_LEVEL)
        mx = np.where(at_vertex, 2.0 ** (2 - EPS_LEVEL), mx)
        u = np.where(at_vertex, mx, u)
        w = np.where(at_vertex, mx, w)
        _, ex = np.frexp(mx)                       # mx in [2^(ex-1), 2^ex)
        level = np.clip(2 - ex, 2, MAX_LEVEL)
        scale = np.ldexp(1.0, level)
        P, Q = u * scale, w * scale
        p = np.clip(np.floor(P), 0, 3).astype(int)
        q = np.clip(np.floor(Q), 0, 3).astype(int)
        inner = (p < 2) & (q < 2)
        p = np.where(inner, 2, p)                  # rounding at the ring's inner edge
        a, b = np.clip(P - p, 0.0, 1.0), np.clip(Q - q, 0.0, 1.0)
        face = self.face_lut[p, q]
        # the sub-cell of the face, and the point in it
        cell = np.empty(n, dtype=int)
        sxw, syw = np.ones(n), np.ones(n)
        for key in set(zip(sector.tolist(), face.tolist())):
            sel = np.nonzero((sector == key[0]) & (face == key[1]))[0]
            xs, ys = self.breaks[key]
            ix = np.clip(np.searchsorted(xs, a[sel], side="right") - 1, 0, len(xs) - 2)
            iy = np.clip(np.searchsorted(ys, b[sel], side="right") - 1, 0, len(ys) - 2)
            cell[sel] = self.first_cell[key] + iy * (len(xs) - 1) + ix
            sxw[sel] = xs[ix + 1] - xs[ix]
            syw[sel] = ys[iy + 1] - ys[iy]
            a[sel] = np.clip((a[sel] - xs[ix]) / sxw[sel], 0.0, 1.0)
            b[sel] = np.clip((b[sel] - ys[iy]) / syw[sel], 0.0, 1.0)
        # one product per (cell, level) met, not per point
        key, inv = np.unique(cell * (MAX_LEVEL + 1) + level, return_inverse=True)
        uc, ul = np.divmod(key, MAX_LEVEL + 1)
        ctrl = np.einsum("npc,ncd->npd", self.Z[uc], self.d[ul])[inv.reshape(-1)]      # (n, 16, 4)
        # the limit's share separately, relative to its first coefficient: where it is
        # constant its derivatives are exactly zero (no rounding of O(1) terms near S)
        zinf = self.Zinf[cell]
        z0 = zinf[:, :1]
        bs = bernstein(3, a)                                       # (n, 3, 4)
        bt = bernstein(3, b)
        H = np.empty((6, 4, n))
        # the differences and the limit's share beyond the cell's first coefficient together
        # (exactly the differences where that share is constant), then the Bernstein sums as
        # batched 4 x 4 products: (n, c, j, i) @ (n, 1, i, 1) -> (n, c, j)
        c4 = (ctrl + (zinf - z0)[:, :, None] * self.limit[None, None, :]).reshape(n, 4, 4, -1)
        X = c4.transpose(0, 3, 1, 2)                                # (n, c, j [y], i [x])
        along_x = [np.matmul(X, bs[:, da][:, None, :, None])[..., 0] for da in range(3)]   # (n, c, j)
        for k, (da, db) in enumerate(DERIVS):
            H[k] = np.matmul(along_x[da], bt[:, db][:, :, None])[..., 0].T
        H[0] += z0[:, 0][None, :] * self.limit[:, None]
        scale_derivatives(H, scale / (dx * sxw), scale / (dy * syw))
        if at_vertex.any():
            H[0][:, at_vertex] = self.limit[:, None]
        return H, at_vertex


_ROT = np.array([[[1.0, 0.0], [0.0, 1.0]], [[0.0, -1.0], [1.0, 0.0]], [[-1.0, 0.0], [0.0, -1.0]],
                 [[0.0, 1.0], [-1.0, 0.0]]])         # twalk.rot(q) as matrices


class StarCells:
    """Cells on the first faces of stars: the subdivided part (``StarLevels``) of sector
    ``sector``, a cell's (a, b) in [0, 1]^2 being the chart point R_q (w_a a, w_b b) + shift
    (``entries``: (star, sector, q, shift (2,), (w_a, w_b)))."""

    kind = "star"

    def __init__(self, stars: list, entries: list):
        self.stars = stars                                          # StarLevels
        self.star = np.array([e[0] for e in entries], dtype=int)
        self.sector = np.array([e[1] for e in entries], dtype=int)
        self.rot = np.array([e[2] for e in entries], dtype=int)
        self.shift = np.array([e[3] for e in entries], dtype=float).reshape(-1, 2)
        self.width = np.array([e[4] for e in entries], dtype=float).reshape(-1, 2)

    def __len__(self) -> int:
        return len(self.star)

    def evaluate(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray):
        n = len(a)
        H = np.empty((6, 4, n))
        at_vertex = np.zeros(n, bool)
        normal = np.zeros((n, 3))
        J = _ROT[self.rot[idx]] * self.width[idx][:, None, :]      # d chart / d (a, b)
        cx = J[:, 0, 0] * a + J[:, 0, 1] * b + self.shift[idx, 0]
        cy = J[:, 1, 0] * a + J[:, 1, 1] * b + self.shift[idx, 1]
        for s in np.unique(self.star[idx]):
            sel = np.nonzero(self.star[idx] == s)[0]
            Hs, atv = self.stars[s].evaluate(self.sector[idx[sel]], cx[sel], cy[sel])
            H[:, :, sel] = _chain(Hs, J[sel])
            if atv.any():
                at_vertex[sel[atv]] = True
                normal[sel[atv]] = self.stars[s].normal
        return H, (at_vertex if at_vertex.any() else None), (normal if at_vertex.any() else None)


class SumCells:
    """Cells whose surface is the sum of two groups' homogeneous parts (a Bezier piece of
    plain B-splines and the subdivided part of a star): cell i is cell ``first[i]`` of
    ``a`` plus cell ``second[i]`` of ``b``."""

    kind = "sum"

    def __init__(self, a, first, b, second):
        self.a, self.b = a, b
        self.first = np.asarray(first, dtype=int)
        self.second = np.asarray(second, dtype=int)

    def __len__(self) -> int:
        return len(self.first)

    def evaluate(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray):
        Ha, _, _ = self.a.evaluate(self.first[idx], a, b)
        Hb, at_vertex, normal = self.b.evaluate(self.second[idx], a, b)
        return Ha + Hb, at_vertex, normal
