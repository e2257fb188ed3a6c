"""The HTML report of the keycap job (coarse: scallop 0.1 mm) checked for content: every
picture referenced and there, of its size, not blank, in the patch colours; the tables carry
the figures of the metrics objects; nothing external; the same inputs give the same bytes.

Two full reports are written, once for the class: ``a`` of the job as made, ``b`` of the same
objects with a three-axis baseline of its own tool axes; every picture but the baseline's and
the page outside its baseline section are the same bytes in both (the second report drawn in
a process that drew one already), and ``b``'s baseline table is checked against the program.
(The whole page and every picture, the baseline's too, are compared between two processes in
tests/test_batch.py.)"""
import contextlib
import os
import re
import shutil
import tempfile
import time
import unittest
from html.parser import HTMLParser

import numpy as np
from PIL import Image

from tsplcam.report import figures, report, style, write_report
from tsplcam.report.example import job_objects
from tsplcam.verify.metrics import path_metrics

PICTURES = ("layout", "path", "scallop", "axis", "machine", "clearance", "time", "baseline")


class Page(HTMLParser):
    """Images, links, scripts, tables (by id: rows of cell texts) and headline cards."""

    def __init__(self, text):
        super().__init__()
        self.images, self.links, self.scripts, self.tables, self.cards = [], [], 0, {}, {}
        self._table = self._row = self._cell = None
        self._card = None
        self._div = []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.images.append(a)
        elif tag in ("a", "link"):
            self.links.append(a)
        elif tag == "script":
            self.scripts += 1
        elif tag == "table":
            self._table = self.tables.setdefault(a.get("id", f"anon{len(self.tables)}"), [])
        elif tag == "tr" and self._table is not None:
            self._row = []
            self._table.append(self._row)
        elif tag in ("td", "th") and self._row is not None:
            self._cell = ""
        elif tag == "div":
            cls = a.get("class", "")
            self._div.append(cls)
            if cls.startswith("card"):
                self._card = [a.get("id"), []]
            elif self._card is not None and cls in ("k", "v", "n"):
                self._card[1].append("")

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append(self._cell.strip())
            self._cell = None
        elif tag == "table":
            self._table = self._row = None
        elif tag == "div" and self._div:
            cls = self._div.pop()
            if cls.startswith("card") and self._card is not None:
                self.cards[self._card[0]] = self._card[1]
                self._card = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data
        elif self._card is not None and self._card[1] and self._div and self._div[-1] in ("k", "v", "n"):
            self._card[1][-1] += data

    def key_values(self, ident):
        return {r[0]: r[1] for r in self.tables[ident] if len(r) == 2}


def num(text: str) -> float:
    return float(text.replace(",", ""))


class KeycapReport(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="tsplcam-report-")
        cls.job = job_objects(scallop=0.1, baseline_axes="normal")
        cls.saved = report.CLEARANCE_POSES
        report.CLEARANCE_POSES = 600                      # a shorter clearance sweep for the test
        cls.out = [os.path.join(cls.tmp, k) for k in ("a", "b")]
        # b: the same objects, the baseline three-axis with its own tool axes
        from tsplcam.program import Program
        base = cls.job["baseline"]
        cls.own_axes = dict(cls.job, baseline=Program(base.with_axis(np.tile([0.0, 0.0, 1.0], (len(base), 1)))))
        cls.html = [write_report(cls.out[0], **cls.job), write_report(cls.out[1], **cls.own_axes)]
        with open(cls.html[0], encoding="utf-8") as fh:
            cls.text = fh.read()
        cls.page = Page(cls.text)
        cls._colours = {}

    @classmethod
    def tearDownClass(cls):
        report.CLEARANCE_POSES = cls.saved
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def picture(self, name):
        return np.asarray(Image.open(os.path.join(self.out[0], report.FILES, f"{name}.png")).convert("RGB"), int)

    def test_every_picture_referenced_present_sized_and_drawn(self):
        srcs = [im["src"] for im in self.page.images]
        self.assertEqual(sorted(srcs), sorted(f"{report.FILES}/{n}.png" for n in PICTURES))
        self.assertEqual(sorted(os.listdir(os.path.join(self.out[0], report.FILES))),
                         sorted(f"{n}.png" for n in PICTURES))
        for im in self.page.images:
            name = im["src"].split("/")[-1][:-4]
            px = self.picture(name)
            w, h = figures.pixel_size(name)
            self.assertEqual(px.shape[:2], (h, w), name)
            self.assertEqual((int(im["width"]), int(im["height"])), (w, h), name)
            ink = np.count_nonzero((px < 235).any(axis=2)) / (w * h)
            self.assertGreater(ink, 0.05, f"{name}: only {ink:.1%} of the picture is drawn")
            # laid out inside the picture: its outer two pixels blank, no label cut at an edge
            edge = np.concatenate([px[:2].reshape(-1, 3), px[-2:].reshape(-1, 3), px[:, :2].reshape(-1, 3),
                                   px[:, -2:].reshape(-1, 3)])
            self.assertTrue((edge >= 250).all(), f"{name}: drawn up to its edge")
            self.assertTrue(im.get("alt"), name)

    def colour_pixels(self, name, rgba, tol=40):
        """Pixels within ``tol`` (0..255, each channel) of a colour."""
        if name not in self._colours:
            px = self.picture(name).reshape(-1, 3)
            packed, counts = np.unique((px[:, 0] << 16) | (px[:, 1] << 8) | px[:, 2], return_counts=True)
            self._colours[name] = (np.column_stack([packed >> 16, (packed >> 8) & 255, packed & 255]), counts)
        colours, counts = self._colours[name]
        c = np.asarray(rgba[:3]) * 255
        return int(counts[np.abs(colours - c).max(axis=1) <= tol].sum())

    def test_patch_colours_in_the_pictures(self):
        colours = style.patch_colours(len(self.job["model"].patches))
        for name in ("path", "axis", "machine", "clearance", "time"):
            counts = [self.colour_pixels(name, c) for c in colours]
            self.assertTrue(all(n > 40 for n in counts), f"{name}: patch colour pixels {counts}")
        # the layout: every extraordinary point a red dot in both views
        self.assertGreater(self.colour_pixels("layout", (0.839, 0.153, 0.157, 1.0), tol=30), 8 * 40)

    def test_offline(self):
        self.assertEqual(self.page.scripts, 0)
        self.assertEqual(self.page.links, [])
        self.assertNotRegex(self.text, r"(?i)(https?:|//|file:)")
        for im in self.page.images:
            self.assertFalse(os.path.isabs(im["src"]))
        self.assertNotIn(self.tmp, self.text)

    def test_tables_carry_the_metrics(self):
        j = self.job
        pm = path_metrics(j["oriented"].path)
        kv = self.page.key_values("path-figures")
        self.assertEqual(num(kv["points"]), pm.points)
        self.assertEqual(num(kv["lines"]), pm.lines)
        self.assertEqual(num(kv["retractions"]), pm.retractions)
        self.assertAlmostEqual(num(kv["total length (mm)"]), pm.length, delta=0.05)
        self.assertAlmostEqual(num(kv["cutting length (mm)"]), pm.cut_length, delta=0.05)
        v = j["verification"]
        kv = self.page.key_values("scallop-figures")
        self.assertAlmostEqual(num(kv["largest scallop (µm)"]), v.max_scallop * 1000, delta=5e-4)
        self.assertAlmostEqual(num(kv["mean cusp height (µm)"]), v.cusp_mean * 1000, delta=5e-4)
        self.assertEqual(num(kv["surface samples"]), v.samples)
        m = j["oriented"].metrics
        kv = self.page.key_values("orientation-figures")
        self.assertEqual(num(kv["collisions (flutes, shank, holder)"]), m.collisions)
        self.assertAlmostEqual(num(kv["largest axis step (deg)"]), m.max_step_deg, delta=5e-4)
        self.assertAlmostEqual(num(kv["rotary travel (deg)"]), m.rotary_travel_deg, delta=0.05)
        tr = j["posted"].time
        kv = self.page.key_values("time-figures")
        self.assertIn(f"({tr.total_s:,.1f} s)", kv["total"])
        self.assertIn(f"({tr.feed_only_s:,.1f} s)", kv["length over feed alone"])
        rows = self.page.tables["time-axes"][1:]
        self.assertEqual([r[0] for r in rows], list(tr.axis_names))
        for r, travel, limits in zip(rows, tr.travel, tr.limiting_blocks):
            self.assertAlmostEqual(num(r[2]), travel, delta=0.05)
            self.assertEqual(num(r[6]), limits)
        self.assertAlmostEqual(sum(num(r[7]) for r in rows) + num(kv["set by the feed (s)"]), tr.total_s, delta=0.4)
        joints = j["posted"].joints
        for r, k in zip(self.page.tables["machine-axes"][1:], range(5)):
            lo = joints[:, k].min() + (j["posted"].settings["tool_length"] if k == 2 else 0.0)
            self.assertAlmostEqual(num(r[2]), lo, delta=5e-4)
        steps = self.page.tables["processing-list"][1:]
        self.assertEqual([int(r[1]) for r in steps], j["processing_list"].order)
        base = path_metrics(j["baseline"])
        table = {r[0]: r[1:] for r in self.page.tables["baseline"][1:]}
        self.assertEqual([num(x) for x in table["retractions"]], [path_metrics(j["path"]).retractions, base.retractions])
        self.assertEqual([num(x) for x in table["air moves"]], [path_metrics(j["path"]).air_moves, base.air_moves])
        self.assertAlmostEqual(num(table["total length (mm)"][1]), base.length, delta=0.05)
        self.assertGreater(base.retractions, 0)
        clearance = {r[0]: num(r[1]) for r in self.page.tables["clearance"][1:]}
        self.assertEqual(sorted(clearance), ["holder", "shank"])
        # the orientation kept 0.3 mm between shank/holder and the part
        self.assertGreaterEqual(min(clearance.values()), 0.3 - 0.01)

    def test_baseline_with_its_own_axes_is_timed_against_the_program(self):
        j = self.own_axes                        # report b: a three-axis baseline
        with open(self.html[1], encoding="utf-8") as fh:
            page = Page(fh.read())
        table = {r[0]: r[1:] for r in page.tables["baseline"][1:]}
        self.assertEqual(num(table["machining time (s)"][0]), round(j["posted"].time.total_s, 1))
        self.assertEqual(num(table["points"][0]), len(j["oriented"].path))

    def test_headline(self):
        j = self.job
        c = self.page.cards
        self.assertEqual(num(c["h-points"][1]), len(j["oriented"].path))
        self.assertEqual(num(c["h-retractions"][1]), 0)
        self.assertEqual(num(c["h-collisions"][1]), 0)
        self.assertEqual(c["h-scallop"][1], f"{j['verification'].max_scallop * 1000:.2f} µm")
        self.assertIn(f"{j['posted'].time.feed_only_s:,.1f} s", c["h-time"][2])
        title = re.search(r"<title>(.*?)</title>", self.text).group(1)
        self.assertIn(j["model"].name, title)
        for ident in ("model", "tool", "machine-info", "path-settings", "job-settings"):
            self.assertIn(ident, self.page.tables)
        self.assertEqual(self.page.key_values("tool")["name"], "ball1_keycap")
        self.assertEqual(self.page.key_values("job-settings")["scallop"], "0.1")

    def test_same_inputs_same_bytes(self):
        """Reports a and b differ in their baseline only: the page outside its baseline section
        and every other picture are the same bytes."""
        a, b = self.out
        with open(self.html[1], encoding="utf-8") as fh:
            other = fh.read()
        cut = re.compile(r'<section id="baseline">.*?</section>', flags=re.S)
        self.assertEqual(len(cut.findall(self.text)), 1)
        self.assertNotEqual(cut.search(other).group(0), cut.search(self.text).group(0))
        self.assertEqual(cut.sub("", other), cut.sub("", self.text))
        for n in PICTURES:
            if n == "baseline":
                continue
            with open(os.path.join(a, report.FILES, f"{n}.png"), "rb") as fa, \
                    open(os.path.join(b, report.FILES, f"{n}.png"), "rb") as fb:
                self.assertEqual(fa.read(), fb.read(), n)

    def test_clearance_started_ahead_gives_the_same_report(self):
        """The job's clearance measurement started before the report (``make_job``'s
        ``report_ahead``, in a forked process while the verification's last patch is measured)
        and handed to it: the same page and pictures as report a, which started its own."""
        from types import SimpleNamespace

        from tsplcam.job import _clearance_ahead
        from tsplcam.orientation.aside import Aside
        job = SimpleNamespace(program=self.job["oriented"], tool=self.job["tool"], clearance=None)
        _clearance_ahead(job)()
        if Aside.can_fork():
            self.assertTrue(job.clearance.forked)
        out = os.path.join(self.tmp, "c")
        from unittest import mock
        with mock.patch.object(report, "ClearanceSweep", side_effect=AssertionError("measured again")) \
                if job.clearance is not None else contextlib.nullcontext():
            html = write_report(out, **dict(self.job, clearance=job.clearance))
        with open(html, encoding="utf-8") as fh:
            self.assertEqual(fh.read(), self.text)
        for n in PICTURES:
            with open(os.path.join(self.out[0], report.FILES, f"{n}.png"), "rb") as fa, \
                    open(os.path.join(out, report.FILES, f"{n}.png"), "rb") as fc:
                self.assertEqual(fa.read(), fc.read(), n)

    def test_clearance_sweep_shared_by_two_processes(self):
        """The clearance series measured by the sweep (a forked process takes the holder's
        first, this one what is left when it asks at once) and by a sweep whose process was
        stopped before delivering (this process measures what it took): the values one process
        gives, series by series."""
        from tsplcam.orientation.aside import Aside
        checker, final = self.job["oriented"].checker, self.job["oriented"].path
        one = {name: report.clearance_group(checker, final, parts)
               for name, parts in report.clearance_groups(checker).items()}
        self.assertEqual(list(one), ["shank", "holder"])
        sweeps = [report.ClearanceSweep(checker, final) for _ in range(2)]
        self.assertEqual(sweeps[0].order, ["holder", "shank"])
        self.assertEqual(sweeps[0].forked, Aside.can_fork())
        if sweeps[1].forked:                                 # its process stopped once it took one
            end = time.monotonic() + 10.0
            while sweeps[1]._next.value < 1 and time.monotonic() < end:
                time.sleep(0.002)
            self.assertEqual(sweeps[1]._next.value, 1)
        sweeps[1].close()
        for sweep in sweeps:
            got = sweep.result()
            sweep.close()
            self.assertEqual(list(got), list(one))
            for name in one:
                for a, b in zip(got[name], one[name]):
                    np.testing.assert_array_equal(a, b, err_msg=name)

    def test_missing_pieces_leave_their_sections_out(self):
        out = os.path.join(self.tmp, "bare")
        html = write_report(out, model=self.job["model"], path=self.job["path"])
        with open(html, encoding="utf-8") as fh:
            page = Page(fh.read())
        self.assertEqual(sorted(im["src"] for im in page.images),
                         sorted(f"{report.FILES}/{n}.png" for n in ("layout", "path", "axis")))
        self.assertEqual(sorted(os.listdir(os.path.join(out, report.FILES))), ["axis.png", "layout.png", "path.png"])
        self.assertIn("h-time", page.cards)                 # length over feed stands in for the time
        for ident in ("scallop-figures", "machine-axes", "clearance", "time-axes", "baseline"):
            self.assertNotIn(ident, page.tables)


if __name__ == "__main__":
    unittest.main()
