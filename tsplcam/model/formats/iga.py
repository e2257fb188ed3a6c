"""``.iga`` files: T-spline Bezier extraction as written by the Rhino T-splines plug-in
(docs/formats.md section 1).

Grammar (one record per line; blank lines and ``#`` lines are comments; CRLF is fine;
tags are case-insensitive and ``=`` counts as a separator, as in MSolve's reader)::

    type plane|surface            nodeN <int>            elemN <int>
    node x y z w                  (Cartesian point and weight, not homogeneous)
    belem nsh p q                 then one line of nsh 0-based node indices,
                                  then nsh rows of (p+1)(q+1) extraction coefficients
    set n node|side|elem NAME ... (side sets: element and LEFT|RIGHT|BOTTOM|TOP)
    domain nel ndof ...           (domain decomposition blocks: skipped)

Row a of an element's operator C holds the Bernstein coefficients of global function
idx_a; Bernstein index k = j (p+1) + i with i along s (s fastest). The element is the
rational Bezier patch with homogeneous control points Q_k = sum_a C[a, k] w_a (x_a, 1)
(docs/formats.md section 1.2: rational evaluation is mandatory; the column sums of C are
not 1 next to extraordinary points). LEFT/RIGHT/BOTTOM/TOP are s=0/s=1/t=0/t=1.

``volume`` and ``thickened_surface`` files are refused. Lines that start with a space are
read like any other (GeoPDEs skips them as comments; no real file relies on that). Every
error names the file and the line of the record. Geometry (which elements meet, T-junctions,
extraordinary points, patches) is recovered by ``tsplcam.model.bezier_mesh``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from ...errors import InputError
from ...inputfile import (coordinate_error, excerpt, first_coordinate_error, line_of, naming,
                          split_lines, weight_error)

TYPES = ("plane", "surface")
SIDES = {"LEFT": 3, "RIGHT": 1, "BOTTOM": 0, "TOP": 2}     # element side -> patch-style edge number
_SPLIT = re.compile(r"[\s=]+")
# Largest |extraction coefficient|: the Bernstein coefficients of B-spline blending functions
# lie in [0, 1] (slightly outside next to extraordinary points); 1e3 leaves room and keeps the
# Bezier weights, and every product the evaluation forms, far from overflow.
EXTRACTION_LIMIT = 1e3


@dataclass
class IgaElement:
    """One Bezier element as read: degrees (p along s, q along t), global node indices (nsh,),
    extraction operator (nsh, (p+1)(q+1)) and the line of its ``belem`` record."""
    p: int
    q: int
    nodes: np.ndarray
    C: np.ndarray
    line: int


@dataclass
class IgaSet:
    kind: str                 # 'node', 'side' or 'elem'
    name: str
    items: list               # node ids, element ids, or (element, side name) pairs
    line: int


@dataclass
class IgaFile:
    """The content of an ``.iga`` file: ``points`` (n, 3) and ``weights`` (n,) of the
    global functions, the elements, named sets."""
    path: str
    type: str
    points: np.ndarray
    weights: np.ndarray
    elements: list[IgaElement]
    sets: dict[str, IgaSet] = field(default_factory=dict)

    def bezier_control(self, e: int) -> np.ndarray:
        """Homogeneous Bezier control points (q+1, p+1, 4) of element e, index [j, i]."""
        el = self.elements[e]
        H = np.column_stack([self.points[el.nodes] * self.weights[el.nodes, None],
                             self.weights[el.nodes]])
        return (el.C.T @ H).reshape(el.q + 1, el.p + 1, 4)


class _Lines:
    """Content lines of a file with their 1-based numbers, comments and blanks removed."""

    def __init__(self, path: str, text: str):
        self.path = path
        self.items = []
        for ln, raw in enumerate(split_lines(text), start=1):
            s = raw.strip()
            if s and not s.startswith("#"):
                self.items.append((ln, [t for t in _SPLIT.split(s) if t]))
        self.pos = 0

    def next(self):
        if self.pos >= len(self.items):
            return None, None
        item = self.items[self.pos]
        self.pos += 1
        return item

    def peek_tag(self):
        if self.pos >= len(self.items):
            return None
        tok = self.items[self.pos][1][0]
        return tok.lower() if tok[:1].isalpha() else None

    def error(self, message: str, line: int | None) -> InputError:
        return InputError(message, path=self.path, line=line)


def _int(lines: _Lines, tok: str, ln: int, what: str) -> int:
    try:
        return int(tok)
    except ValueError:
        raise lines.error(f"{what}: {excerpt(tok, 40)} is not an integer", ln)


def _floats(lines: _Lines, toks, ln: int, what: str) -> np.ndarray:
    try:
        vals = np.array([float(t) for t in toks])
    except ValueError:
        bad = next(t for t in toks if not _is_float(t))
        raise lines.error(f"{what}: {excerpt(bad, 40)} is not a number", ln)
    if not np.all(np.isfinite(vals)):
        raise lines.error(f"{what}: a value is not a finite number", ln)
    return vals


def _is_float(t: str) -> bool:
    try:
        float(t)
        return True
    except ValueError:
        return False


def read_iga(path: str) -> IgaFile:
    """Parse an ``.iga`` file (checks counts, indices, row lengths; no geometry yet)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=path)
    if b"\0" in data[:4096]:
        raise InputError("binary data, not an .iga text file", path=path,
                         line=line_of(data, data.index(b"\0")))
    lines = _Lines(path, data.decode("utf-8", errors="replace"))
    header: dict[str, tuple[object, int]] = {}
    points, weights, node_lines = [], [], []
    elements: list[IgaElement] = []
    sets: dict[str, IgaSet] = {}
    while True:
        ln, tok = lines.next()
        if ln is None:
            break
        tag = tok[0].lower()
        if tag == "type":
            if len(tok) < 2:
                raise lines.error("'type' needs a value (plane or surface)", ln)
            kind = tok[1].lower()
            if kind not in TYPES:
                raise lines.error(f"type {excerpt(tok[1], 40)} is not supported: tsplcam reads T-spline "
                                  f"surfaces (type plane or surface)", ln)
            header["type"] = (kind, ln)
        elif tag in ("noden", "elemn"):
            if len(tok) < 2:
                raise lines.error(f"'{tok[0]}' needs a count", ln)
            n = _int(lines, tok[1], ln, tok[0])
            if n < 0:
                raise lines.error(f"'{tok[0]}' is negative", ln)
            header[tag] = (n, ln)
        elif tag == "node":
            _need_header(lines, header, ln)
            if len(tok) != 5:
                raise lines.error(f"a node needs x y z w, found {len(tok) - 1} values", ln)
            vals = _floats(lines, tok[1:], ln, "node")
            why = coordinate_error(vals[:3]) or weight_error(vals[3])
            if why:
                raise lines.error(f"node {len(points)}: {why}", ln)
            points.append(vals[:3])
            weights.append(vals[3])
            node_lines.append(ln)
        elif tag == "belem":
            _need_header(lines, header, ln)
            elements.append(_read_element(lines, tok, ln, header["noden"][0], len(elements)))
        elif tag == "set":
            s = _read_set(lines, tok, ln)
            sets[s.name] = s
        elif tag == "domain":
            while lines.peek_tag() is None and lines.pos < len(lines.items):
                lines.next()
        else:
            raise lines.error(f"unknown record {excerpt(tok[0], 40)}", ln)
    _need_header(lines, header, None)
    n_nodes, ln_nodes = header["noden"]
    n_elem, ln_elem = header["elemn"]
    if len(points) != n_nodes:
        raise lines.error(f"nodeN says {n_nodes} nodes but the file has {len(points)} node "
                          f"lines" + (" (truncated?)" if len(points) < n_nodes else ""), ln_nodes)
    if len(elements) != n_elem:
        raise lines.error(f"elemN says {n_elem} elements but the file has {len(elements)}"
                          + (" (truncated?)" if len(elements) < n_elem else ""), ln_elem)
    if not elements:
        raise lines.error("no elements", ln_elem)
    for s in sets.values():
        _check_set(lines, s, len(points), len(elements))
    return IgaFile(path, header["type"][0], np.array(points, float).reshape(-1, 3),
                   np.array(weights, float), elements, sets)


def _need_header(lines: _Lines, header: dict, ln: int | None) -> None:
    for key, name in (("type", "type"), ("noden", "nodeN"), ("elemn", "elemN")):
        if key not in header:
            where = "before this record" if ln is not None else "in the file"
            if ln is None:      # the header belongs before the first record (or on line 1)
                ln = lines.items[0][0] if lines.items else 1
            raise lines.error(f"no '{name}' line {where}: the header is type, nodeN, elemN", ln)


def _read_element(lines: _Lines, tok, ln: int, n_nodes: int, index: int) -> IgaElement:
    what = f"element {index}"
    if len(tok) == 5:
        raise lines.error(f"{what} has three degrees: volume elements are not supported", ln)
    if len(tok) != 4:
        raise lines.error(f"'belem' needs nsh p q, found {len(tok) - 1} values", ln)
    nsh = _int(lines, tok[1], ln, what)
    p = _int(lines, tok[2], ln, what)
    q = _int(lines, tok[3], ln, what)
    if nsh < 1 or p < 1 or q < 1 or p > 20 or q > 20:
        raise lines.error(f"{what}: nsh {nsh}, degrees ({p}, {q}) are not usable", ln)
    nb = (p + 1) * (q + 1)

    def content(expect: str):
        if lines.peek_tag() is not None or lines.pos >= len(lines.items):
            at = lines.items[lines.pos][0] if lines.pos < len(lines.items) else None
            raise lines.error(f"{what} (belem at line {ln}) ends early: expected {expect}"
                              + ("" if at is not None else " before the end of the file"),
                              at if at is not None else ln)
        return lines.next()

    ln_idx, idx_tok = content(f"{nsh} node indices")
    if len(idx_tok) != nsh:
        raise lines.error(f"{what}: {len(idx_tok)} node indices where belem says {nsh}", ln_idx)
    nodes = np.array([_int(lines, t, ln_idx, what) for t in idx_tok], dtype=int)
    bad = (nodes < 0) | (nodes >= n_nodes)
    if bad.any():
        raise lines.error(f"{what}: node index {nodes[bad][0]} is outside 0..{n_nodes - 1} "
                          f"(indices are 0-based)", ln_idx)
    if len(np.unique(nodes)) != nsh:
        raise lines.error(f"{what}: a node index is listed twice", ln_idx)
    C = np.empty((nsh, nb))
    for a in range(nsh):
        ln_row, row = content(f"{nsh} rows of {nb} coefficients, found {a}")
        if len(row) != nb:
            raise lines.error(f"{what}: extraction row {a + 1} has {len(row)} coefficients, "
                              f"degree ({p}, {q}) needs {nb}", ln_row)
        C[a] = _floats(lines, row, ln_row, f"{what}, extraction row {a + 1}")
        if np.abs(C[a]).max() > EXTRACTION_LIMIT:
            raise lines.error(f"{what}, extraction row {a + 1}: coefficient "
                              f"{C[a][np.argmax(np.abs(C[a]))]:g} is beyond +-{EXTRACTION_LIMIT:g} "
                              f"(Bezier coefficients of blending functions are about 1)", ln_row)
    return IgaElement(p, q, nodes, C, ln)


def _read_set(lines: _Lines, tok, ln: int) -> IgaSet:
    if len(tok) < 4:
        raise lines.error("'set' needs a count, a kind (node, side, elem) and a name", ln)
    n = _int(lines, tok[1], ln, "set")
    kind = tok[2].lower()
    name = tok[3]
    rest = tok[4:]
    if kind in ("node", "elem"):
        if len(rest) != n:
            raise lines.error(f"set {name}: {len(rest)} ids where the count says {n}", ln)
        return IgaSet(kind, name, [_int(lines, t, ln, f"set {name}") for t in rest], ln)
    if kind == "side":
        if len(rest) != 2 * n:
            raise lines.error(f"set {name}: {len(rest) // 2} sides where the count says {n}", ln)
        items = []
        for e, pos in zip(rest[0::2], rest[1::2]):
            pos = pos.upper()
            if pos not in SIDES:
                raise lines.error(f"set {name}: side {excerpt(pos, 40)} is not LEFT, RIGHT, BOTTOM "
                                  f"or TOP", ln)
            items.append((_int(lines, e, ln, f"set {name}"), pos))
        return IgaSet(kind, name, items, ln)
    raise lines.error(f"set kind {excerpt(tok[2], 40)} is not node, side or elem", ln)


def _check_set(lines: _Lines, s: IgaSet, n_nodes: int, n_elem: int) -> None:
    ids = [x[0] if isinstance(x, tuple) else x for x in s.items]
    limit = n_nodes if s.kind == "node" else n_elem
    for i in ids:
        if not 0 <= i < limit:
            raise lines.error(f"set {s.name}: {s.kind if s.kind != 'side' else 'element'} {i} "
                              f"is outside 0..{limit - 1}", s.line)


def iga_model(path: str, name: str | None = None):
    """The Model of an ``.iga`` file (see ``model_from_iga``)."""
    iga = read_iga(path)
    with naming(path):
        return model_from_iga(iga, name)


def model_from_iga(iga: IgaFile, name: str | None = None):
    """The elements of ``iga`` as rational Bezier cells grouped into four-sided patches
    (``tsplcam.model.bezier_mesh``); ``model.iga`` keeps the file's content and
    ``model.elements`` where each element sits in its patch."""
    from ..bezier_mesh import bezier_model
    nets, labels = [], []
    for e, el in enumerate(iga.elements):
        Q = iga.bezier_control(e)
        if not np.all(np.isfinite(Q)):
            raise InputError(f"element {e}: its Bezier control points are not finite numbers",
                             path=iga.path, line=el.line)
        W = Q[..., 3]
        if not np.all(W > 0):
            raise InputError(f"element {e}: Bezier weight {W.min():.3g} <= 0, the rational "
                             f"surface is not defined everywhere", path=iga.path, line=el.line)
        with np.errstate(over="ignore"):                  # an overflow is refused just below
            bad = first_coordinate_error((Q[..., :3] / W[..., None]).reshape(-1, 3))
        if bad is not None:
            raise InputError(f"element {e}: Bezier control point {bad[0]}: {bad[1]}",
                             path=iga.path, line=el.line)
        nets.append(Q)
        labels.append((f"element {e}", el.line))
    model = bezier_model(nets, iga.path, labels, kind=f"t-spline (iga, {iga.type})", name=name)
    model.iga = iga
    return model


__all__ = ["read_iga", "iga_model", "model_from_iga", "IgaFile", "IgaElement", "IgaSet", "SIDES"]
