"""Autodesk T-Splines T-meshes (``.tsm``, ``#TS0200``; docs/formats.md section 2).

What the records mean (facts from the files and from GrapeTec's T-SPLINE reader,
``rhparser``/``rhspreader``; no code taken from it):

* ``f <link> 0`` faces, ``e <link> <interval>`` edges with their knot interval,
  ``v <link> <NORTH|WEST|SOUTH|EAST>`` vertices (one outgoing half-edge and the direction it
  points to in the vertex's own frame), ``l <prev> <next> <opp> <vertex> <face> <edge>
  <flag>`` half-edges ("links"): ``vertex`` is the link's origin, face -1 marks the
  boundary side. Every kind is numbered by order of appearance from 0; a bare keyword is a
  null slot (a bare ``f`` is a deleted face: a hole). In a face loop, flag 0 marks a
  corner of the face and flag 1 a T-junction; on the boundary, flag 2 marks a convex
  corner, 1 a straight vertex and 0 a concave corner.
* ``0g x y z w``: control points ("grips"), in order. ``0m gvp i`` / ``0m gv i`` (one per
  grip, same order) give the vertex a grip belongs to; ``gvp`` is the vertex's own point.
  All shipped files have w = 1; x, y, z are read as Cartesian coordinates.
* With Bezier end conditions (``force-bezier-end-conditions 1``) every boundary vertex
  carries a small block of grips, ``0m cg <vertex> 4 <n> <w> <s> <e> <grip ids>``: n, w, s,
  e rows or columns of extra grips north, west, south and east of the vertex's own grip in
  the vertex's frame (the frame in which its ``v`` link points the given direction),
  listed wedge by wedge in a pinwheel around the middle (id -1: no grip there). The
  extras are the second row of a clamped B-spline: a straight boundary vertex has one, a
  convex corner three, a concave corner seven (a 3 x 3 block without the corner outside).

The importer turns this into a tsplcam T-mesh with the T-spline boundary rule (a ray that
leaves the mesh repeats the last knot): the .tsm faces keep their knot intervals, every
boundary vertex takes its innermost grip, and a ring of faces of zero width is added
outside the boundary for the boundary grips (zero knot intervals: a clamped boundary),
with a zero-size face at each convex corner; at a concave corner the two boundary edges
get two vertices each at zero distance from the corner for the block's side grips. The
ring-view position of every grip (its place in that construction) is checked against the
block's layout, so a file whose blocks do not fit is refused rather than read wrongly.

A boundary vertex of four faces or more (a star point on the boundary) has no grip block:
its own grip is its Catmull-Clark control point, and the file is read through the Fusion
dialect's kernel route (``tsm_fusion.grapetec_star_model``: every vertex's control point
its grip on the boundary ring, the blocks kept away from the stars and checked against the
edge-and-corner rule within their rings).

Units: ``units <metres per unit> <name>``; coordinates are scaled to mm. Records the
importer does not support (other end conditions, degrees, edge conditions, grip blocks of
boundary stars, unknown records) are refused with their line. Display and editing
metadata (``100001uv``, ``100001uvr``, ``50000grip``, ``105sym``, ``105plane``, ``105a``,
``tol``, ``ver``) is skipped.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from ...inputfile import COORDINATE_LIMIT, coordinate_error, excerpt, naming, split_lines, weight_error

#: editor data (selection, symmetry, display parameters): skipped
SKIPPED = {"100001uv", "100001uvr", "50000grip", "105sym", "105plane", "105a", "105r"}
#: footer metadata, kept in ``TsmInfo.footer``: tolerances (numbers) and versions (text)
FOOTER = {"tol": float, "geom-tol": float, "ver": int, "behavior-version": str, "compat-version": str}
CAP_TYPES = ("1", "G1CAPS")
#: the end conditions of files written through Fusion / ASM (docs/formats.md section 2.5)
FUSION_END_CONDITIONS = ("MULTIPLE_KNOTS", "SUBD_CREASES")
STAR_KNOT_RULES = ("NURCCS",)
#: Fusion's coordinates are centimetres whatever the units line says
FUSION_MM_PER_UNIT = 10.0
DIRECTIONS = {"EAST": 0, "NORTH": 1, "WEST": 2, "SOUTH": 3}
UNIT_NAMES = {"millimeters": 0.001, "centimeters": 0.01, "meters": 1.0, "inches": 0.0254, "feet": 0.3048}
_STEP = ((1, 0), (0, 1), (-1, 0), (0, -1))

# grip positions in the ring construction, per boundary vertex type (quarter turns of faces)
PATTERNS = {
    1: {(0, 0), (-1, -1), (0, -1), (-1, 0)},
    2: {(0, 0), (0, -1)},
    3: {(0, 0), (1, 0), (2, 0), (0, -1), (0, -2), (1, -1), (2, -1), (1, -2)},
}
SHIFT = {1: (-1, -1), 2: (0, -1), 3: (1, -1)}
TYPE_NAMES = {1: "convex corner", 2: "straight boundary", 3: "concave corner"}


@dataclass
class TsmInfo:
    """What a ``.tsm`` file said and how it was read (``Model.tsm``)."""
    dialect: str               # "fusion" (end-conditions ...) or "rhino" (force-bezier-end-conditions)
    end_conditions: str
    cap_type: str
    star_smoothness: int
    star_knot_rule: str | None
    mm_per_unit: float         # the scale applied to the file's coordinates
    scale_rule: str            # which rule gave it, in words
    surface: str               # how the surface was built, in words
    crease_edges: int          # infinitely sharp crease edges (100edges, interior ones)
    sharp_vertices: int        # infinitely sharp vertices (100verts)
    footer: dict               # tol, geom-tol, ver, behavior-version, compat-version as given

    @classmethod
    def of(cls, r, surface: str, crease_edges: int = 0, sharp_vertices: int = 0) -> "TsmInfo":
        h = r.header
        return cls(r.dialect, h["end-conditions"][0], h["cap-type"][0], h["star-smoothness"][0],
                   h.get("star-knot-rule", (None,))[0], r.scale, r.scale_rule, surface, crease_edges,
                   sharp_vertices, {k: v for k, (v, _) in r.footer.items()})


def _rot(q, x, y):
    for _ in range(q % 4):
        x, y = -y, x
    return x, y


def block_offsets(dims, grips):
    """Grip ids of a ``cg`` block by their offset (east, north) from the vertex's own grip,
    in the vertex's frame. dims = (north, west, south, east) counts."""
    d0, d1, d2, d3 = dims
    need = d0 * (d1 + 1) + d1 * (d2 + 1) + d2 * (d3 + 1) + d3 * (d0 + 1)
    if len(grips) != need:
        raise ValueError(f"a block of {dims} needs {need} grip ids, the record has {len(grips)}")
    out = {}
    pos = 0

    def wedge(rows, cols, turns, r0, c0):
        nonlocal pos
        ids = np.arange(rows * cols).reshape(rows, cols) if rows * cols else np.zeros((rows, cols), int)
        ids = np.rot90(ids, turns)
        for r in range(ids.shape[0]):
            for c in range(ids.shape[1]):
                g = grips[pos + int(ids[r, c])]
                if g >= 0:
                    out[(c0 + c - d1, d0 - (r0 + r))] = g
        pos += rows * cols

    wedge(d0, d1 + 1, 2, 0, 0)                 # north-west
    wedge(d1, d2 + 1, 3, d0, 0)                # south-west
    wedge(d2, d3 + 1, 0, d0 + 1, d1)           # south-east
    wedge(d3, d0 + 1, 1, 0, d1 + 1)            # north-east
    return out


class _Reader:
    def __init__(self, path):
        self.path = os.fspath(path)

    def err(self, msg, line=None):
        return InputError(msg, path=self.path, line=line)

    # -- records ---------------------------------------------------------------------------------
    def parse(self):
        try:
            with open(self.path, "rb") as fh:
                raw = fh.read()
        except OSError as exc:
            raise self.err(f"cannot read: {exc.strerror}")
        text = raw.decode("latin-1")              # comments may be GBK; records are ASCII
        lines = split_lines(text)
        self.n_lines = len(lines)
        first = next((k for k, l in enumerate(lines) if l.strip()), None)
        if first is None or not lines[first].split() or lines[first].split()[0] != "#TS0200":
            raise self.err("not a T-Splines T-mesh file (the first line must be #TS0200)", 1)
        self.f, self.e, self.v, self.l, self.ec = [], [], [], [], []
        self.grip_of, self.cg, self.g = [], {}, []
        self.header = {}
        self.footer = {}
        self.dialect = "rhino"
        self.grip_map_line = None             # the line of '0m odd-grip-map'
        self.crease_edges, self.crease_vertices = [], []      # (line, id)
        self.ek = []                          # 106ek: (line, interval)
        order = ["degree", "cap-type", "star-smoothness", "units", "end-conditions"]
        for ln, raw_line in enumerate(lines[first + 1:], start=first + 2):
            body = raw_line.split("#", 1)[0]
            tok = body.split()
            if not tok:
                continue
            key = tok[0]
            try:
                if order:
                    want = order[0]
                    if key == "force-bezier-end-conditions":
                        key = "end-conditions"
                    if key != want:
                        raise self.err(f"the header must give {want!r} here (order: degree, cap-type, "
                                       f"star-smoothness, units, end conditions); found "
                                       f"{excerpt(tok[0], 40)}", ln)
                    order.pop(0)
                    self._header(key, tok, ln)
                    continue
                self._record(key, tok, ln)
            except (ValueError, IndexError):
                raise self.err(f"cannot read the record {excerpt(body)}", ln)
        if order:
            raise self.err(f"the header ends before {order[0]!r}: the file is truncated", len(lines))
        if not any(g is not None for g in self.g):
            raise self.err("no control points (0g records): the file is truncated or empty", len(lines))

    def _header(self, key, tok, ln):
        if len(tok) < 2:
            raise self.err(f"{key} needs a value", ln)
        if key == "degree":
            if int(tok[1]) != 3:
                raise self.err(f"degree {tok[1]} is not supported (T-splines here are bicubic)", ln)
        elif key == "cap-type":
            if tok[1] not in CAP_TYPES:
                raise self.err(f"cap-type {excerpt(tok[1], 40)} is not supported (1 or G1CAPS)", ln)
            self.header["cap-type"] = (tok[1], ln)
        elif key == "star-smoothness":
            value = int(tok[1])
            if value < 0:
                raise self.err(f"star-smoothness {value} is not a smoothness (0, 1, 2, ...)", ln)
            self.header["star-smoothness"] = (value, ln)
        elif key == "units":
            value = float(tok[1])
            name = tok[2] if len(tok) > 2 else ""
            if not value > 0 or not value < float("inf"):
                raise self.err(f"units {tok[1]}: the unit length must be a positive number", ln)
            if name and name not in UNIT_NAMES:
                raise self.err(f"unknown unit name {excerpt(name, 40)} (known: {', '.join(UNIT_NAMES)})", ln)
            self.header["units"] = (value, name, ln)
        elif key == "end-conditions":
            value = tok[1]
            if tok[0] == "end-conditions":
                if value not in FUSION_END_CONDITIONS:
                    raise self.err(f"end-conditions {excerpt(value, 40)} are not supported "
                                   f"({' or '.join(FUSION_END_CONDITIONS)})", ln)
                self.dialect = "fusion"
            elif value != "1":
                raise self.err(f"end conditions force-bezier-end-conditions {excerpt(value, 40)} are not supported "
                               f"(only 1, or the Fusion dialect's end-conditions)", ln)
            self.header["end-conditions"] = (value, ln)
            self._set_scale()

    def _set_scale(self):
        """mm per file unit: Fusion writes centimetres whatever its units line says; the
        older files give metres per unit on the units line (a known unit name must agree)."""
        value, name, ln = self.header["units"]
        if self.dialect == "fusion":
            self.scale = FUSION_MM_PER_UNIT
            said = f"{value:g} {name}".strip()
            self.scale_rule = (f"centimetres, as Fusion writes them (1 file unit = 10 mm); the units "
                               f"line ({said}, line {ln}) is not used")
            return
        if name in UNIT_NAMES and abs(UNIT_NAMES[name] - value) > 1e-9 * value:
            raise self.err(f"units {value:g} does not match the unit name {excerpt(name, 40)}", ln)
        self.scale = value * 1000.0
        self.scale_rule = f"the units line (line {ln}): {value:g} m per file unit (1 file unit = {self.scale:g} mm)"

    def _ids(self, tok, ln, what):
        ids = [int(x) for x in tok[1:]]
        if any(i < 0 for i in ids):
            raise self.err(f"{tok[0]}: a negative {what} id", ln)
        return [(ln, i) for i in ids]

    def _record(self, key, tok, ln):
        n = len(tok)
        fusion = self.dialect == "fusion"
        if key == "f":
            if n > 1 and int(tok[2] if n > 2 else 0) != 0:
                raise self.err(f"face flag {tok[2]} is not supported", ln)
            self.f.append((ln, int(tok[1])) if n > 1 else None)
        elif key == "e":
            if n > 1 and not 0 <= float(tok[2]) <= COORDINATE_LIMIT:       # NaN fails too
                raise self.err(f"edge {len(self.e)}: knot interval {tok[2]} is not a number in "
                               f"[0, {COORDINATE_LIMIT:g}]", ln)
            self.e.append((ln, int(tok[1]), float(tok[2])) if n > 1 else None)
        elif key == "v":
            if n > 1 and tok[2] not in DIRECTIONS:
                raise self.err(f"vertex direction {excerpt(tok[2], 40)} is not one of NORTH, WEST, SOUTH, "
                               f"EAST", ln)
            self.v.append((ln, int(tok[1]), DIRECTIONS[tok[2]]) if n > 1 else None)
        elif key == "l":
            self.l.append((ln, *[int(x) for x in tok[1:8]]) if n > 1 else None)
            if n > 1 and n < 8:
                raise self.err("a link needs: previous next opposite vertex face edge flag", ln)
        elif key == "ec":
            if int(tok[2]) != 0:
                raise self.err(f"edge condition {tok[2]} on edge {tok[1]} is not supported (only 0)", ln)
            self.ec.append((ln, int(tok[1])))
        elif key == "0m":
            kind = tok[1]
            if kind == "odd-grip-map":
                if self.grip_map_line is not None:
                    raise self.err(f"a second '0m odd-grip-map' (the first is on line {self.grip_map_line})", ln)
                self.grip_map_line = ln
                return
            if self.grip_map_line is None:
                raise self.err(f"grip map record '0m {excerpt(kind, 20)}' before '0m odd-grip-map'", ln)
            if kind in ("gvp", "gv"):
                if fusion and kind == "gv":
                    raise self.err("extra grips ('0m gv') are not part of the Fusion dialect (its files "
                                   "give every vertex one grip)", ln)
                self.grip_of.append((ln, int(tok[2]), kind == "gvp"))
            elif kind == "cg":
                if fusion:
                    raise self.err("grip blocks ('0m cg') are not part of the Fusion dialect (they belong "
                                   "to force-bezier-end-conditions 1)", ln)
                vertex, valence = int(tok[2]), int(tok[3])
                if valence != 4:
                    raise self.err(f"a grip block of valence {valence} (a star point on the boundary) is "
                                   f"not supported: a boundary star point of four faces or more is read "
                                   f"without a grip block, its own grip its Catmull-Clark control point "
                                   f"(docs/formats.md section 2.2)", ln)
                dims = [int(x) for x in tok[4:8]]
                grips = [int(x) for x in tok[8:]]
                if vertex in self.cg:
                    raise self.err(f"a second grip block for vertex {vertex}", ln)
                self.cg[vertex] = (ln, dims, grips)
            else:
                raise self.err(f"grip map record '0m {excerpt(kind, 20)}' is not supported", ln)
        elif key == "0g":
            if n == 1:
                self.g.append(None)               # a null slot (its grip map entry is vertex -1)
                return
            x, y, z = (float(t) for t in tok[1:4])
            w = float(tok[4]) if n > 4 else 1.0
            why = coordinate_error([self.scale * x, self.scale * y, self.scale * z]) or weight_error(w)
            if why:
                raise self.err(f"control point {len(self.g)}: {why}", ln)
            self.g.append((ln, x, y, z, w))
        elif key == "star-knot-rule":
            if n < 2 or tok[1] not in STAR_KNOT_RULES:
                raise self.err(f"star-knot-rule {excerpt(' '.join(tok[1:]), 40)} is not supported (only "
                               f"NURCCS, the T-NURCC rule)", ln)
            self.header["star-knot-rule"] = (tok[1], ln)
        elif key == "100edges" and fusion:
            self.crease_edges += self._ids(tok, ln, "edge")
        elif key == "100verts" and fusion:
            self.crease_vertices += self._ids(tok, ln, "vertex")
        elif key == "106ek" and fusion:
            value = float(tok[1])
            if not 0 <= value <= COORDINATE_LIMIT:
                raise self.err(f"106ek: knot interval {tok[1]} is not a number in [0, {COORDINATE_LIMIT:g}]", ln)
            self.ek.append((ln, value))
        elif key in FOOTER:
            if key in self.footer:
                raise self.err(f"a second {key!r} (the first is on line {self.footer[key][1]})", ln)
            value = FOOTER[key](tok[1])
            if FOOTER[key] is float and not abs(value) < float("inf"):
                raise self.err(f"{key} {tok[1]} is not a number", ln)
            self.footer[key] = (value, ln)
        elif key in SKIPPED:
            return
        else:
            raise self.err(f"record {excerpt(key, 40)} is not supported", ln)

    # -- the .tsm's own T-mesh ----------------------------------------------------------------------
    def link(self, i, ln):
        if not (0 <= i < len(self.l)) or self.l[i] is None:
            raise self.err(f"refers to link {i}, which does not exist", ln)
        return self.l[i]

    def topology(self):
        """Face loops (old vertex ids), corners, intervals of the file's own T-mesh."""
        from ..tmesh import TMesh
        L = self.l
        for i, rec in enumerate(L):             # references first, each at its own line
            if rec is None:
                continue
            ln, prev, nxt, opp, vert, face, edge, flag = rec
            for j in (prev, nxt, opp):
                self.link(j, ln)
            if not (-1 <= face < len(self.f)) or (face >= 0 and self.f[face] is None):
                raise self.err(f"link {i} lies on face {face}, which does not exist", ln)
        for i, rec in enumerate(L):
            if rec is None:
                continue
            ln, prev, nxt, opp, vert, face, edge, flag = rec
            o = self.link(opp, ln)
            nx_ = self.link(nxt, ln)
            if o[3] != i:
                raise self.err(f"link {i}: its opposite link {opp} does not point back to it", ln)
            if o[4] != nx_[4]:
                raise self.err(f"link {i}: the origin of its opposite ({o[4]}) is not the origin of its next "
                               f"({nx_[4]})", ln)
            if not (0 <= vert < len(self.v)) or self.v[vert] is None:
                raise self.err(f"link {i} starts at vertex {vert}, which does not exist", ln)
            if not (0 <= edge < len(self.e)) or self.e[edge] is None:
                raise self.err(f"link {i} lies on edge {edge}, which does not exist", ln)
        for vi, rec in enumerate(self.v):
            if rec is not None and self.link(rec[1], rec[0])[4] != vi:
                raise self.err(f"vertex {vi}: its link {rec[1]} starts at vertex {self.l[rec[1]][4]}", rec[0])
        loops, corners, intervals, face_lines, face_ids = [], [], [], [], []
        for fi, rec in enumerate(self.f):
            if rec is None:
                continue                          # a hole
            ln, start = rec
            loop, cs, d = [], [], []
            cur = start
            for _ in range(len(L) + 1):
                lrec = self.link(cur, ln)
                if lrec[5] != fi:
                    raise self.err(f"face {fi}: its loop reaches link {cur} of face {lrec[5]}", ln)
                if lrec[7] == 0:
                    cs.append(len(loop))
                elif lrec[7] != 1:
                    raise self.err(f"face {fi}: link {cur} has flag {lrec[7]} (0 corner or 1 T-junction)", lrec[0])
                loop.append(lrec[4])
                d.append(self.e[lrec[6]][2])
                cur = lrec[2]
                if cur == start:
                    break
            else:
                raise self.err(f"face {fi}: its loop of links does not close", ln)
            if len(cs) != 4:
                raise self.err(f"face {fi} has {len(cs)} corners (links with flag 0): a face has four", ln)
            loops.append(loop)
            corners.append(cs)
            intervals.append(d)
            face_lines.append(ln)
            face_ids.append(fi)
        if not loops:
            raise self.err("no faces (every face record is empty)", self.n_lines)
        used = sorted({v for loop in loops for v in loop})
        for vi, rec in enumerate(self.v):
            if rec is not None and vi not in set(used):
                raise self.err(f"vertex {vi} is not used by any face", rec[0])
        self.old_ids = used
        self.compact = {v: k for k, v in enumerate(used)}
        mesh = TMesh(np.zeros((len(used), 3)), None, [[self.compact[v] for v in loop] for loop in loops],
                     corners, intervals, source=self.path,
                     face_lines=face_lines,
                     vertex_labels=[f"vertex {v} (line {self.v[v][0]})" for v in used],
                     vertex_lines=[self.v[v][0] for v in used],
                     face_labels=[f"face {fi} (line {ln})" for fi, ln in zip(face_ids, face_lines)])
        mesh.validate()
        self.face_ids = face_ids
        return mesh

    # -- grips ----------------------------------------------------------------------------------------
    def mapped_grips(self):
        """The grip map's entries (grip, line, vertex, own grip?) without the null ones,
        after checking there is one per control point and nulls go together."""
        if len(self.grip_of) != len(self.g):
            last = next((g[0] for g in reversed(self.g) if g is not None), self.grip_map_line)
            raise self.err(f"{len(self.grip_of)} grip map records (0m gvp/gv) for {len(self.g)} control "
                           f"points (0g): the file is truncated or inconsistent", last)
        for gi, (ln, v, is_prime) in enumerate(self.grip_of):
            if (v < 0) != (self.g[gi] is None):
                raise self.err(f"grip {gi}: a null grip map entry (vertex -1) must go with a null control "
                               f"point (a bare 0g) and only with one", ln)
            if v >= 0:
                yield gi, ln, v, is_prime

    def grips(self, old):
        """Per old vertex (compact id): {ring-view position: grip id}."""
        topo = old.topology
        prime, extra = {}, {}
        for gi, ln, v, is_prime in self.mapped_grips():
            if v not in self.compact:
                raise self.err(f"grip {gi} belongs to vertex {v}, which no face uses", ln)
            if is_prime:
                if v in prime:
                    raise self.err(f"vertex {v} has two grips of its own (gvp)", ln)
                prime[v] = gi
            else:
                extra.setdefault(v, set()).add(gi)
        out = {}
        for v in self.old_ids:
            k = self.compact[v]
            vrec = self.v[v]
            if v not in prime:
                raise self.err(f"vertex {v} has no grip of its own (0m gvp)", vrec[0])
            T = int(topo.total[k])
            boundary = bool(topo.boundary[k])
            if v not in self.cg:
                if boundary and T >= 4 and not extra.get(v):
                    out[k] = {(0, 0): prime[v]}     # a boundary star point (tsm_fusion.grapetec_star_model)
                    continue
                if boundary:
                    raise self.err(f"boundary vertex {v} has no grip block (0m cg): only Bezier end "
                                   f"conditions are supported", vrec[0])
                if extra.get(v):
                    raise self.err(f"vertex {v} has extra grips but no grip block", vrec[0])
                out[k] = {(0, 0): prime[v]}
                continue
            ln, dims, gids = self.cg[v]
            if not boundary:
                if any(dims):
                    raise self.err(f"grip block of interior vertex {v}: not supported", ln)
                out[k] = {(0, 0): prime[v]}
                continue
            if T not in PATTERNS:
                raise self.err(f"boundary vertex {v} has faces of {T} quarter turns and a grip block: a "
                               f"boundary star point is read without one (its own grip its Catmull-Clark "
                               f"control point)", vrec[0])
            try:
                local = block_offsets(dims, gids)
            except ValueError as exc:
                raise self.err(f"grip block of vertex {v}: {exc}", ln)
            if set(local.values()) != extra.get(v, set()):
                raise self.err(f"grip block of vertex {v} lists grips {sorted(local.values())}, the grip map "
                               f"gives it {sorted(extra.get(v, set()))}", ln)
            # the vertex's frame: its link points DIR; in the fan that link is at angle a_ref
            _, ref, direction = vrec
            lrec = self.link(ref, vrec[0])
            if lrec[4] != v:
                raise self.err(f"vertex {v}: its link {ref} starts at vertex {lrec[4]}", vrec[0])
            w = self.link(lrec[2], vrec[0])[4]              # the link's end (origin of next)
            a_ref = topo.edge_angle.get((k, self.compact.get(w, -1)))
            if a_ref is None:
                raise self.err(f"vertex {v}: its link {ref} is not an edge of the mesh", vrec[0])
            turn = a_ref - direction
            sx, sy = SHIFT[T]
            pos = {(0 + sx, 0 + sy): prime[v]}
            for (dx, dy), g in local.items():
                x, y = _rot(turn, dx, dy)
                pos[(x + sx, y + sy)] = g
            if set(pos) != PATTERNS[T]:
                raise self.err(f"grip block of vertex {v} does not fit a {TYPE_NAMES[T]}: its grips sit at "
                               f"{sorted(pos)} around it", ln)
            out[k] = pos
        return out

    # -- the tsplcam T-mesh -----------------------------------------------------------------------------
    def build(self, old=None, pos=None, G=None, grip_lines=None, grip_names=None, origin=None):
        """The T-mesh with the boundary made explicit. By default from the file's grips and
        blocks; the Fusion dialect passes its own T-mesh ``old``, ring-view positions
        ``pos`` and grips ``G`` ((x, y, z, w) rows, file units) with their lines and names,
        and for a T-mesh cut along creases the vertex of the file's T-mesh every vertex of
        ``old`` was copied from (``origin``)."""
        from ..tmesh import TMesh
        own = pos is None
        old = self.topology() if old is None else old
        topo = old.topology
        if own:
            pos = self.grips(old)
            G = np.array([g[1:5] if g is not None else (np.nan,) * 4 for g in self.g], float)
            grip_lines = [g[0] if g is not None else None for g in self.g]
        glines = grip_lines
        names = grip_names or [f"grip {g} (line {ln})" for g, ln in enumerate(glines)]
        P, labels, vlines = [], [], []
        vid = {}                                           # (old vertex, ring-view position) -> new id

        def vertex(k, p):
            key = (k, p)
            if key not in vid:
                g = pos[k][p]
                vid[key] = len(P)
                P.append(G[g])
                vlines.append(glines[g])
                if p == (0, 0):
                    labels.append(old.vertex_labels[k] + f", {names[g].split(' (')[0]}")
                else:
                    labels.append(f"{names[g]} of {old.vertex_labels[k]}")
            return vid[key]

        for k in range(old.n_vertices):
            vertex(k, (0, 0))
        faces = [list(f) for f in old.faces]
        corners = [list(c) for c in old.corners]
        intervals = [list(d) for d in old.intervals]
        face_labels = list(old.face_labels)
        face_lines = list(old.face_lines)
        # boundary edges (a -> b) with the face on their left, each with its chain of vertices
        ring_faces = set()

        def add_face(loop, cs, d, label, line):
            key = frozenset(loop)
            if key in ring_faces:
                return
            ring_faces.add(key)
            faces.append(loop)
            corners.append(cs)
            intervals.append(d)
            face_labels.append(label)
            face_lines.append(line)

        for (a, b), (f, i) in sorted(topo.edge_at.items()):
            if (b, a) in topo.edge_at:
                continue
            Ta, Tb = int(topo.total[a]), int(topo.total[b])
            if topo.edge_angle[(a, b)] != 0 or topo.edge_angle[(b, a)] != Tb:
                raise AssertionError("boundary fans")
            L = old.intervals[f][i]
            chain = [(a, (0, 0))]
            if Ta == 3:
                chain += [(a, (1, 0)), (a, (2, 0))]
            start_main = len(chain) - 1
            if Tb == 3:
                chain += [(b, (0, -2)), (b, (0, -1))]
            chain.append((b, (0, 0)))
            d = [0.0] * (len(chain) - 1)
            d[start_main] = L
            ids = [vertex(k, p) for k, p in chain]
            # the old face: replace edge i by the chain (new vertices are T-junctions)
            loop = faces[f]
            j = next(j for j in range(len(loop)) if loop[j] == a and loop[(j + 1) % len(loop)] == b)
            faces[f] = loop[:j + 1] + ids[1:-1] + loop[j + 1:]
            corners[f] = [c + len(ids) - 2 if c > j else c for c in corners[f]]
            intervals[f] = intervals[f][:j] + d + intervals[f][j + 1:]
            # ring faces outside, one per chain edge: (offset p, offset q, q, p)
            na = _STEP[3]                                      # right of the walk along a's +x
            nb = _STEP[(Tb + 1) % 4]                           # right of the arrival at b
            oa, ob = (a, b) if origin is None else (origin[a], origin[b])
            e_id = self.l[self._link_of(oa, ob)][6]
            e_line = self.e[e_id][0]
            for (kp, pp), (kq, pq), dd in zip(chain[:-1], chain[1:], d):
                op = (pp[0] + (na if kp == a else nb)[0], pp[1] + (na if kp == a else nb)[1])
                oq = (pq[0] + (na if kq == a else nb)[0], pq[1] + (na if kq == a else nb)[1])
                loop_r = [vertex(kp, op), vertex(kq, oq), vertex(kq, pq), vertex(kp, pp)]
                add_face(loop_r, [0, 1, 2, 3], [dd, 0.0, dd, 0.0],
                         f"boundary strip of edge {e_id} (line {e_line})", e_line)
            if Ta == 1:
                loop_c = [vertex(a, (-1, -1)), vertex(a, (0, -1)), vertex(a, (0, 0)), vertex(a, (-1, 0))]
                add_face(loop_c, [0, 1, 2, 3], [0.0] * 4, f"boundary corner at {old.vertex_labels[a]}",
                         old.vertex_lines[a])
        P = np.array(P, float)
        mesh = TMesh(P[:, :3] * self.scale, P[:, 3], faces, corners, intervals, source=self.path,
                     face_lines=face_lines, vertex_lines=vlines, vertex_labels=labels,
                     face_labels=face_labels,
                     name=os.path.splitext(os.path.basename(self.path))[0])
        mesh.validate()
        used = {pos[k][p] for k, p in vid}
        unused = [g for g in range(len(self.g)) if g not in used and self.g[g] is not None]
        if own and unused:
            raise self.err(f"grip {unused[0]} is not placed by the grip map", self.g[unused[0]][0])
        stars = [k for k in range(old.n_vertices) if topo.is_extraordinary(k)]
        if stars and self.header.get("star-smoothness", (0, None))[0] != 0:
            ln = self.header["star-smoothness"][1]
            raise self.err("star points with star-smoothness other than 0 are not supported", ln)
        return mesh

    def _link_of(self, a, b):
        """The link of the file from compact old vertex a to b."""
        va, vb = self.old_ids[a], self.old_ids[b]
        if not hasattr(self, "_links_by_ends"):
            self._links_by_ends = {}
            for i, rec in enumerate(self.l):
                if rec is None:
                    continue
                end = self.l[rec[2]][4]
                self._links_by_ends[(rec[4], end)] = i
        return self._links_by_ends[(va, vb)]


def _parse(path) -> _Reader:
    reader = _Reader(path)
    reader.scale = 1.0
    reader.parse()
    return reader


def read_tsm(path):
    """The T-mesh of a .tsm file with Bezier end conditions, boundary made explicit (see the
    module docstring)."""
    reader = _parse(path)
    if reader.dialect == "fusion":
        raise reader.err("a Fusion-dialect file (end-conditions) has no T-mesh with explicit boundary "
                         "grips: read it with tsm_model", reader.header["end-conditions"][1])
    old = reader.topology()
    star = next((k for k in range(old.n_vertices) if old.topology.boundary[k] and old.topology.total[k] >= 4),
                None)
    if star is not None:
        raise reader.err(f"vertex {reader.old_ids[star]} is a star point on the boundary: the file has no T-mesh "
                         f"with explicit boundary grips there (local Catmull-Clark cages): read it with "
                         f"tsm_model", old.vertex_lines[star])
    return reader.build(old)


def tsm_model(path, **options):
    """The surface of a .tsm file, either dialect (the Fusion one: ``tsm_fusion``)."""
    from ..tspline import tspline_model
    reader = _parse(path)
    if reader.dialect == "fusion":
        from .tsm_fusion import fusion_model
        return fusion_model(reader, **options)
    old = reader.topology()
    if any(old.topology.boundary[k] and old.topology.total[k] >= 4 for k in range(old.n_vertices)):
        from .tsm_fusion import grapetec_star_model
        return grapetec_star_model(reader, old)
    mesh = reader.build(old)
    with naming(path):
        model = tspline_model(mesh, name=mesh.name)
    model.tsm = TsmInfo.of(reader, "T-spline with Bezier end conditions (boundary grip blocks)")
    return model
