"""Figures for the report. Each function returns PNG bytes (deterministic for equal inputs)."""

from __future__ import annotations

import functools
import gc
import io
import json
import struct
import textwrap
import zlib

import matplotlib
import matplotlib.text

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.layout_engine import TightLayoutEngine  # noqa: E402
from matplotlib.ticker import NullFormatter  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.spines import Spine  # noqa: E402
from matplotlib.transforms import Bbox  # noqa: E402
from PIL import Image  # noqa: E402

from wsnloc.campaign import Campaign  # noqa: E402

TECH_STYLE = {"uwb": ("tab:red", "^"), "zigbee": ("tab:blue", "o"), "cricket": ("tab:green", "s")}
LABEL_OFFSET = {"uwb": (4, -10), "zigbee": (4, 3)}   # points; keeps co-located anchors readable
TRACK_FRAME_MARGIN = 0.5   # trajectory panels: the truth's box widened by half its larger side each way


PNG_DPI = 110
# PNG text chunk listing the pairs of texts that overlap in the figure, as JSON
# [[text, text], ...]; read back by wsnloc.report.browser_check.
OVERLAPS_KEY = "wsnloc-text-overlaps"
OVERLAP_TOLERANCE_PX = 1.0      # boxes that share less than this (width and height) only touch


def gc_paused(build):
    """Decorator of a function that builds, draws and closes a figure: Python's cyclic
    garbage collector paused meanwhile. The figure's artists (about 10^4 to 10^5 container
    objects, alive until the figure is closed) would trigger collections that traverse the
    job's whole heap and find nothing to free; the closed figure is collected afterwards,
    by the collector's next run."""
    @functools.wraps(build)
    def paused(*args, **kwargs):
        if not gc.isenabled():
            return build(*args, **kwargs)
        gc.disable()
        try:
            return build(*args, **kwargs)
        finally:
            gc.enable()
    return paused


def _drawn_texts(fig) -> list:
    """Visible, non-empty Text artists of the figure, without tick labels outside the view
    (matplotlib keeps those artists but does not draw them)."""
    undrawn = set()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            low, high = sorted(axis.get_view_interval())
            span = 1e-9 * max(abs(low), abs(high), 1.0)
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                if not low - span <= tick.get_loc() <= high + span:
                    undrawn.update((id(tick.label1), id(tick.label2)))
    return [t for t in fig.findobj(matplotlib.text.Text)
            if t.get_visible() and t.get_text().strip() and id(t) not in undrawn]


def text_overlaps(fig, dpi: float = PNG_DPI, drawn: bool = False) -> list[tuple[str, str]]:
    """Pairs of texts whose rendered bounding boxes (pixels at `dpi`) overlap, measured with
    the figure's renderer after a layout pass (drawn: the figure was just drawn at `dpi`,
    so no second pass is needed); see _overlapping."""
    fig.set_dpi(dpi)
    if not drawn:
        fig.draw_without_rendering()
    return _overlapping(*_text_boxes(fig, fig.canvas.get_renderer()))


def _text_boxes(fig, renderer) -> tuple[list, np.ndarray]:
    """The drawn texts (_drawn_texts) and their boxes (n, 4): x0, y0, x1, y1 in pixels, from
    Text.get_window_extent with `renderer` (the layout of its last draw)."""
    texts = _drawn_texts(fig)
    return texts, np.array([t.get_window_extent(renderer).extents for t in texts]).reshape(-1, 4)


def _overlapping(texts: list, boxes: np.ndarray) -> list[tuple[str, str]]:
    """Pairs of texts whose boxes (n, 4: x0, y0, x1, y1 in pixels) overlap: their
    intersection is wider and taller than OVERLAP_TOLERANCE_PX."""
    x0, y0, x1, y1 = (boxes[:, [k]] for k in range(4))
    width = np.minimum(x1, x1.T) - np.maximum(x0, x0.T)       # of the intersection of boxes i and j
    height = np.minimum(y1, y1.T) - np.maximum(y0, y0.T)
    overlap = np.triu((width > OVERLAP_TOLERANCE_PX) & (height > OVERLAP_TOLERANCE_PX), k=1)
    return [(texts[i].get_text(), texts[j].get_text()) for i, j in zip(*np.nonzero(overlap))]


def _tight_box(fig, renderer, text_boxes: np.ndarray) -> Bbox:
    """The figure's tight bounding box (inches) from the layout of its last draw: the union of
    the boxes of the axes, of the drawn texts (text_boxes, pixels) and of the other artists
    that Figure.get_tightbbox takes (legends, artists not clipped to their axes), without
    laying out again the ticks and titles, as get_tightbbox does. Spines are left out: they
    lie on the axes' edges, with their tick marks under the tick labels."""
    boxes = [Bbox(row.reshape(2, 2)) for row in text_boxes]
    for artist in fig.get_default_bbox_extra_artists():      # the figure's and its axes' own
        if isinstance(artist, Axes):
            boxes.append(artist.bbox)
        elif not isinstance(artist, (Spine, matplotlib.text.Text)):
            box = artist.get_tightbbox(renderer)
            if box is not None and 0 < box.width < np.inf and 0 < box.height < np.inf:
                boxes.append(box)
    return Bbox.union(boxes).transformed(fig.dpi_scale_trans.inverted())


def to_png(fig, tight: bool = True, palette: bool = True) -> bytes:
    """PNG bytes of the figure (closed afterwards) from a single draw, with the texts that
    overlap on that draw in OVERLAPS_KEY (a tEXt chunk inserted after the PNG header).

    tight False: the caller laid the figure out (fitted_png, bound_figures._fit_slots); the
    canvas is saved as is. tight True: the box savefig(bbox_inches="tight") would save (the
    tight bounding box padded by savefig.pad_inches), its corners moved out to whole pixels
    (_tight_render).
    palette: an indexed PNG (_save_palette_png); False: 24-bit RGB, for images of more than
    256 distinct colours that matter (photographs; a matplotlib colour map has 256)."""
    fig.set_dpi(PNG_DPI)
    if tight:
        rgba, overlaps = _tight_render(fig)
    else:
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        overlaps = text_overlaps(fig, drawn=True)
    buffer = io.BytesIO()
    if palette:
        _save_palette_png(rgba, buffer)
    else:
        Image.fromarray(rgba).convert("RGB").save(buffer, format="png", dpi=(PNG_DPI, PNG_DPI))
    plt.close(fig)
    return _with_text_chunk(buffer.getvalue(), OVERLAPS_KEY, json.dumps(overlaps, ensure_ascii=True))


TIGHT_MARGIN_IN = 0.5     # inches (whole pixels at PNG_DPI) drawn around the figure, for what reaches past its edge


def _tight_render(fig) -> tuple[np.ndarray, list[tuple[str, str]]]:
    """RGBA pixels (rows, columns, 4) of the figure's tight bounding box padded by
    savefig.pad_inches, its corners moved out to whole pixels, and its overlapping texts, from
    one draw of the figure grown by TIGHT_MARGIN_IN on each side; a box reaching past that is
    drawn once more, on itself."""
    area = fig.bbox_inches.padded(TIGHT_MARGIN_IN)
    rgba, overlaps, box = _measured_draw(fig, area)
    rows, columns = _pixel_span(box, rgba.shape[0])
    if rows.start < 0 or columns.start < 0 or rows.stop > rgba.shape[0] or columns.stop > rgba.shape[1]:
        area = box.translated(area.x0, area.y0)
        area = Bbox(np.stack([np.floor(area.p0 * PNG_DPI), np.ceil(area.p1 * PNG_DPI)]) / PNG_DPI)
        rgba, overlaps, box = _measured_draw(fig, area)
        rows, columns = _pixel_span(box, rgba.shape[0])
    return rgba[max(rows.start, 0):rows.stop, max(columns.start, 0):columns.stop], overlaps


def _measured_draw(fig, area: Bbox) -> tuple[np.ndarray, list[tuple[str, str]], Bbox]:
    """One draw of `area` (inches, figure coordinates) by savefig(bbox_inches=area), which
    shifts the figure without laying it out again: its RGBA pixels (row 0 on top), the
    overlapping texts and the padded tight box (inches from the lower left corner of area),
    both measured on that draw (draw_event)."""
    measured = {}

    def measure(event) -> None:
        texts, boxes = _text_boxes(fig, event.renderer)
        measured["overlaps"] = _overlapping(texts, boxes)
        measured["box"] = _tight_box(fig, event.renderer, boxes).padded(matplotlib.rcParams["savefig.pad_inches"])
        measured["shape"] = (int(event.renderer.height), int(event.renderer.width), 4)

    connection = fig.canvas.mpl_connect("draw_event", measure)
    raw = io.BytesIO()
    try:
        fig.savefig(raw, format="rgba", dpi=PNG_DPI, bbox_inches=area)
    finally:
        fig.canvas.mpl_disconnect(connection)
    rgba = np.frombuffer(raw.getbuffer(), dtype=np.uint8).reshape(measured["shape"])
    return rgba, measured["overlaps"], measured["box"]


def _pixel_span(box: Bbox, height: int) -> tuple[slice, slice]:
    """Rows and columns of a canvas `height` pixels high that cover `box` (inches from its
    lower left corner, at PNG_DPI): columns floor(x0 dpi) .. ceil(x1 dpi), rows
    height - ceil(y1 dpi) .. height - floor(y0 dpi) (row 0 on top)."""
    x0, y0 = np.floor(box.p0 * PNG_DPI).astype(int)
    x1, y1 = np.ceil(box.p1 * PNG_DPI).astype(int)
    return slice(height - y1, height - y0), slice(x0, x1)


def _save_palette_png(rgba: np.ndarray, buffer) -> None:
    """An RGBA canvas (rows, columns, 4) as an indexed PNG of at most 256 colours (fast
    octree quantisation): line figures use a few colours and their anti-aliased shades, so
    the image looks the same while the PNG is about 3x smaller and quicker to encode."""
    image = Image.fromarray(rgba).convert("RGB").quantize(256, method=Image.Quantize.FASTOCTREE)
    palette = np.asarray(image.getpalette(), dtype=np.uint8)
    palette[palette >= 253] = 255      # an octree bin averages its colours: the white background came back 254
    image.putpalette(palette.tolist())
    image.save(buffer, format="png", dpi=(PNG_DPI, PNG_DPI))


def fitted_png(fig) -> bytes:
    """to_png of a grid of axes first fitted to its canvas by one measuring pass (tight
    layout: margins and spacing from each axes' tight bounding box, texts included), saved
    as laid out. The engine is run once, not attached: a figure with a layout engine is
    drawn twice more by savefig (renderer probe, layout draw) before the saved draw.
    rect None: the margins are measured once. With its default rect (0, 0, 1, 1) the engine
    measures every axes a second time, at unchanged positions, to fit the subplots into that
    rect: the same margins, up to rounding (left = 0 + left, right = 1 - (1 - right))."""
    fig.set_dpi(PNG_DPI)
    TightLayoutEngine(rect=None).execute(fig)
    return to_png(fig, tight=False)


def _with_text_chunk(png: bytes, key: str, text: str) -> bytes:
    """The PNG with a tEXt chunk (keyword, NUL, Latin-1 text) after its IHDR chunk (PNG spec 11.3.4.3)."""
    data = key.encode("latin-1") + b"\0" + text.encode("latin-1")
    chunk = struct.pack(">I", len(data)) + b"tEXt" + data + struct.pack(">I", zlib.crc32(b"tEXt" + data))
    ihdr_end = 8 + 4 + 4 + 13 + 4          # signature, IHDR length, type, 13 data bytes, CRC
    return png[:ihdr_end] + chunk + png[ihdr_end:]


@gc_paused
def placeholder(message: str) -> bytes:
    """A small figure saying why there is nothing to plot (e.g. no RSS in this dataset)."""
    fig, ax = plt.subplots(figsize=(6, 1.2))
    ax.text(0.5, 0.5, message, ha="center", va="center", fontsize=10)
    ax.set_axis_off()
    return to_png(fig)


def draw_walls(ax, walls, color, lw: float) -> None:
    """Wall segments (x1, y1, x2, y2 in m) as one LineCollection with butt caps, drawn and
    autoscaled like one two-point line per wall (zorder of lines), at the cost of one artist;
    no walls: nothing added (an empty collection would still move the autoscaled limits)."""
    segments = np.asarray(walls, dtype=float).reshape(-1, 2, 2)
    if len(segments):
        ax.add_collection(LineCollection(segments, colors=color, linewidths=lw, capstyle="butt",
                                         zorder=Line2D.zorder))


@gc_paused
def floor_plan(campaign: Campaign, track: pd.DataFrame | None = None, anchors: pd.DataFrame | None = None) -> bytes:
    """Walls (doors as gaps), anchors by technology with their ids, the path and a truth track (m)."""
    anchors = campaign.anchors if anchors is None else anchors
    fig, ax = plt.subplots(figsize=(10, 5.4))
    draw_walls(ax, campaign.walls, color="0.25", lw=2.2)
    if campaign.path is not None:
        pose = campaign.path.evaluate(np.linspace(0, campaign.path.length, 400))
        ax.plot(pose["x"], pose["y"], color="tab:orange", lw=2.5, label=f"path ({campaign.path.length:.1f} m)")
    if track is not None and len(track):
        ax.plot(track["x"], track["y"], color="k", lw=0.8, ls="--", label="truth (run 1)")
    for tech, group in anchors.groupby("tech"):
        color, marker = TECH_STYLE.get(tech, ("tab:gray", "D"))
        ax.scatter(group["x"], group["y"], c=color, marker=marker, s=45, label=f"{tech} ({len(group)})", zorder=3)
        # anchors at one (x, y) (e.g. two heights on one mast) share one label, "A5/A9", not two on top of each other
        for (x, y), same in group.groupby([group["x"].round(2), group["y"].round(2)], sort=False):
            ax.annotate("/".join(same["anchor_id"].astype(str)), (x, y), xytext=LABEL_OFFSET.get(tech, (4, 3)),
                        textcoords="offset points", fontsize=7, color=color)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    ax.set_title(f"{campaign.name}: floor plan")
    return to_png(fig)


# range_error_figure's subplot margins and gap (fractions of the 11 in x 3.8 in figure): room for
# the tick labels, axis labels and titles, and for the anchors' legend right of the right panel
RANGE_ERROR_MARGINS = {"left": 0.06, "right": 0.9, "bottom": 0.13, "top": 0.92, "wspace": 0.2}


@gc_paused
def range_error_figure(errors: pd.DataFrame, title: str, max_points: int = 6000) -> bytes:
    """Range error (measured - true, m): histogram of LOS and NLOS links (left) and error against
    the true distance (right): a sample of the ranges, grey, and each anchor's median per 1 m bin,
    so a per-anchor offset shows as a shifted line and a scale error as a slope. Each histogram
    is one filled step outline (histtype "stepfilled"), not 120 bar patches: the same pixels,
    drawn and laid out at a fraction of the cost. The legends have fixed places (the
    histograms' upper right, the anchors' beside the right panel), not "best" (a search over
    the plotted points), and the margins are fixed (RANGE_ERROR_MARGINS, fractions of the
    figure; the saved box is the tight one), not measured by a layout pass."""
    fig, (hist, dist) = plt.subplots(1, 2, figsize=(11, 3.8), gridspec_kw=RANGE_ERROR_MARGINS)
    bins = np.linspace(-1.0, 5.0, 121)
    for los, color, name in ((True, "tab:green", "LOS"), (False, "tab:purple", "NLOS")):
        e = errors.loc[errors["los"] == los, "error_m"].clip(bins[0], bins[-1]) if len(errors) else []
        if len(e):
            hist.hist(e, bins=bins, histtype="stepfilled", color=color, alpha=0.6, density=True,
                      label=f"{name}: n={len(e)}, median {np.median(e):.3f} m")
    hist.set_xlabel("range error [m] (clipped to [-1, 5])")
    hist.set_ylabel("density")
    hist.set_title(title)
    hist.legend(fontsize=8, loc="upper right")
    if len(errors):
        sample = errors.iloc[:: max(1, len(errors) // max_points)]
        dist.scatter(sample["true_distance_m"], sample["error_m"].clip(-1.0, 5.0), s=3, color="0.7", alpha=0.5)
        for anchor, group in errors.groupby("anchor_id", sort=True):
            medians = group.groupby(np.floor(group["true_distance_m"]))["error_m"].median()
            dist.plot(medians.index + 0.5, medians.clip(-1.0, 5.0), lw=1, label=str(anchor))
        if errors["anchor_id"].nunique() <= 12:
            dist.legend(fontsize=7, ncols=1, title="anchor\n(median\nper 1 m)", title_fontsize=7,
                        loc="upper left", bbox_to_anchor=(1.01, 1.0))
    dist.axhline(0.0, color="k", lw=0.8)
    dist.set_xlabel("true distance [m]")
    dist.set_ylabel("range error [m] (clipped to [-1, 5])")
    dist.set_title("error against distance, per anchor")
    return to_png(fig)


@gc_paused
def rss_vs_distance(rss: pd.DataFrame, fit: dict, configured: dict, title: str, max_points: int = 6000) -> bytes:
    """RSS (dBm) against log distance, coloured by walls crossed (five viridis colours: 0 to 4
    or more, in the legend at the upper right), with the fitted path-loss line; an indexed PNG
    (to_png). One scatter per wall count, each of one colour (drawn as stamped markers, a
    fraction of the cost of a scatter coloured point by point), fewer walls first."""
    if len(rss) == 0:
        return placeholder("no RSS measurements in this dataset")
    fig, ax = plt.subplots(figsize=(7, 4))
    sample = rss.iloc[:: max(1, len(rss) // max_points)]
    walls = sample["walls"].clip(0, 4).to_numpy()
    classes = []
    for count in range(5):
        crossed = sample[walls == count]
        if len(crossed):
            classes.append(ax.scatter(crossed["true_distance_m"], crossed["rss_dbm"], s=4, alpha=0.5,
                                      color=plt.get_cmap("viridis")(count / 4),
                                      label=f"{count}{' or more' if count == 4 else ''}"))
    ax.add_artist(ax.legend(handles=classes, title="walls crossed", fontsize=7, title_fontsize=7,
                            loc="upper right", markerscale=2.5))
    d = np.logspace(np.log10(max(0.3, rss["true_distance_m"].min())), np.log10(rss["true_distance_m"].max()), 50)
    lines = []
    if np.isfinite(fit.get("P0_dBm", np.nan)):
        lines += ax.plot(d, fit["P0_dBm"] - 10 * fit["n"] * np.log10(d), "r-", lw=2,
                         label=f"fit, all links: P0={fit['P0_dBm']:.1f} dBm, n={fit['n']:.2f}, σ={fit['sigma_dB']:.1f} dB")
    if configured.get("p0_dbm") is not None:
        lines += ax.plot(d, configured["p0_dbm"] - 10 * configured["path_loss_exponent"] * np.log10(d), "k--", lw=1.5,
                         label=f"configured (no walls): P0={configured['p0_dbm']:.1f}, n={configured['path_loss_exponent']:.2f}")
    ax.set_xscale("log")
    # plain labels on 1-2-3-5 ticks: less than a decade of distances would get labelled minor ticks
    # (2x10^0, 3x10^0, 4x10^0 ...) that overlap
    ticks = [t for t in (0.3, 0.5, 1, 2, 3, 5, 10, 20, 30, 50, 100) if d[0] <= t <= d[-1]]
    ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("true distance [m]")
    ax.set_ylabel("RSS [dBm]")
    ax.set_title(title)
    if lines:
        ax.legend(handles=lines, fontsize=7, loc="lower left")
    return to_png(fig)


@gc_paused
def imu_resampling(raw: pd.DataFrame, resampled: pd.DataFrame, title: str, window_s: float = 20.0) -> bytes:
    """Body-x specific force: raw samples, naive 5 Hz sub-sampling, and the filtered 5 Hz output."""
    if len(raw) == 0:
        return placeholder("no IMU in this dataset")
    fig, ax = plt.subplots(figsize=(7, 3.6))
    if len(raw):
        moving = raw["t"].iloc[0] + 5.0
        raw = raw[(raw["t"] >= moving) & (raw["t"] <= moving + window_s)]
        res = resampled[(resampled["t"] >= moving) & (resampled["t"] <= moving + window_s)]
        ax.plot(raw["t"], raw["ax"], color="0.75", lw=0.5, label="raw ~500 Hz")
        naive = raw.iloc[::100]
        ax.plot(naive["t"], naive["ax"], "o-", color="tab:red", ms=3, lw=0.8, label="plain sub-sampling (every 100th)")
        ax.plot(res["t"], res["ax"], "s-", color="tab:blue", ms=3, lw=1.2, label="low-pass + decimation, 5 Hz")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("a_x [m/s²]")
    ax.set_title(title)
    ax.legend(fontsize=7)
    return to_png(fig)


@gc_paused
def error_cdf(panels: dict[str, dict[str, np.ndarray]], xmax: float | None = 4.0) -> bytes:
    """Empirical CDFs of position error (m), one panel per title, one curve per label;
    xmax None: 1.2 x the largest 95th percentile of the panel's curves."""
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 3.8), squeeze=False)
    for ax, (title, curves) in zip(axes[0], panels.items()):
        finite = [np.asarray(e, dtype=float)[np.isfinite(e)] for e in curves.values()]
        limit = xmax if xmax is not None else 1.2 * max([np.percentile(e, 95) for e in finite if len(e)] or [1.0])
        for label, errors in curves.items():
            e = np.sort(np.asarray(errors, dtype=float)[np.isfinite(errors)])
            if len(e):
                ax.plot(e, np.arange(1, len(e) + 1) / len(e), lw=1.4, label=f"{label} (median {np.median(e):.2f} m)")
        ax.set_xlim(0, limit)
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
        ax.set_xlabel("position error [m]")
        ax.set_ylabel("CDF")
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=7, loc="lower right")
    return fitted_png(fig)


def trajectory_frame(truth: pd.DataFrame) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) (m) a trajectory panel shows: the truth's bounding box widened on each
    side by TRACK_FRAME_MARGIN of its larger side (at least 1 m), so one diverged estimate does
    not shrink the site to a dot."""
    x0, x1 = truth["x"].min(), truth["x"].max()
    y0, y1 = truth["y"].min(), truth["y"].max()
    margin = max(TRACK_FRAME_MARGIN * max(x1 - x0, y1 - y0), 1.0)
    return x0 - margin, x1 + margin, y0 - margin, y1 + margin


@gc_paused
def trajectories(panels: dict[str, tuple[pd.DataFrame, dict[str, pd.DataFrame]]]) -> bytes:
    """True path and estimated tracks (x, y in m), one panel per title; the axes show the
    trajectory_frame of the truth, and the title says how many estimates lie outside it."""
    fig, axes = plt.subplots(len(panels), 1, figsize=(10, 3.3 * len(panels)), squeeze=False)
    for ax, (title, (truth, tracks)) in zip(axes[:, 0], panels.items()):
        ax.plot(truth["x"], truth["y"], color="k", lw=2.2, label="truth")
        x0, x1, y0, y1 = trajectory_frame(truth)
        outside, total = 0, 0
        for label, track in tracks.items():
            ax.plot(track["x"], track["y"], lw=0.9, marker=".", ms=3, label=label)
            finite = track[np.isfinite(track["x"]) & np.isfinite(track["y"])]
            total += len(finite)
            outside += int((~finite["x"].between(x0, x1) | ~finite["y"].between(y0, y1)).sum())
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        if outside:
            title = f"{title}\n{outside} of {total} estimates outside the frame (truth + {TRACK_FRAME_MARGIN:.0%})"
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return fitted_png(fig)


@gc_paused
def error_over_time(panels: dict[str, dict[str, pd.DataFrame]]) -> bytes:
    """Position error (m) against time t (s, the run's clock: the time origin of the sqrt(PCRB)
    and ANEES plots of the same run), one panel per title."""
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 2.8 * len(panels)), squeeze=False)
    for ax, (title, curves) in zip(axes[:, 0], panels.items()):
        for label, curve in curves.items():
            ax.plot(curve["t"], curve["error_m"], lw=1.0, label=label)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("error [m]")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))     # beside: many curves
    return fitted_png(fig)


@gc_paused
def height_over_time(panels: dict[str, tuple[pd.DataFrame, dict[str, pd.DataFrame]]]) -> bytes:
    """Height z (m) against time t (s, the run's clock) per title: the truth (t, z) and each
    cell's estimate (t, z)."""
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 2.6 * len(panels)), squeeze=False)
    for ax, (title, (truth, curves)) in zip(axes[:, 0], panels.items()):
        ax.plot(truth["t"], truth["z"], color="k", lw=1.8, label="truth")
        for label, curve in curves.items():
            ax.plot(curve["t"], curve["z"], lw=1.0, label=f"{label} estimate")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("z [m]")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return fitted_png(fig)


@gc_paused
def rmse_vs_anchors(curves: dict[str, tuple[list[int], list[float]]], title: str) -> bytes:
    """RMSE (m) against the number of anchors, one line per label."""
    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    for label, (counts, rmse) in curves.items():
        ax.plot(counts, rmse, marker="o", label=label)
    ax.set_xlabel("number of anchors")
    ax.set_ylabel("RMSE [m]")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return to_png(fig)


@gc_paused
def error_histograms(errors: dict[str, pd.Series], title: str, xmax: float = 1.5) -> bytes:
    """Histograms of position error (m), one per label, side by side; each is one filled step
    outline (histtype "stepfilled"), not 30 bar patches: the same pixels at less cost."""
    fig, axes = plt.subplots(1, max(1, len(errors)), figsize=(4.2 * max(1, len(errors)), 3.4), squeeze=False,
                             sharey=True)
    bins = np.linspace(0, xmax, 31)
    for ax, (label, e) in zip(axes[0], errors.items()):
        e = np.asarray(e, dtype=float)
        e = e[np.isfinite(e)]
        ax.hist(np.clip(e, 0, xmax), bins=bins, density=True, histtype="stepfilled", color="tab:blue", alpha=0.75)
        ax.set_title(f"{label}\nmedian {np.median(e):.3f} m" if len(e) else label, fontsize=9)
        ax.set_xlabel("position error [m]")
    axes[0][0].set_ylabel("density")
    fig.suptitle(title, fontsize=10)
    return fitted_png(fig)


CURVE_TITLE_CHARS = 75     # a 10 pt title line of at most this many characters fits the 6.5 in wide figure


@gc_paused
def curve_with_interval(curves: dict[str, pd.DataFrame], xlabel: str, ylabel: str, title: str,
                        references: dict[str, float] | None = None, logy: bool = False,
                        logx: bool = False) -> bytes:
    """One line per label through (x, value) with its 95% interval as a band (frames with
    columns x, value, ci95_low, ci95_high; no band where the interval is NaN, e.g. too few
    runs), each run's value as a small dot where the frame has `run_values` (a list per x),
    and horizontal reference lines (e.g. a paper's value)."""
    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    for label, frame in curves.items():
        line, = ax.plot(frame["x"], frame["value"], marker="o", label=label)
        low, high = frame["ci95_low"].to_numpy(float), frame["ci95_high"].to_numpy(float)
        if np.isfinite(low).any():
            ax.fill_between(frame["x"], low, high, color=line.get_color(), alpha=0.2, lw=0)
        if "run_values" in frame:
            xs, ys = zip(*[(x, v) for x, values in zip(frame["x"], frame["run_values"]) for v in values])
            ax.plot(xs, ys, ls="none", marker=".", ms=4, color=line.get_color(), alpha=0.6, label=f"{label}: each run")
    for (label, value), style in zip((references or {}).items(), ("--", ":", "-.", (0, (5, 1)))):
        ax.axhline(value, color="0.3", ls=style, lw=1.2, label=label)
    if logy:
        ax.set_yscale("log")
    if logx:
        ax.set_xscale("log", base=2)
        ticks = sorted({float(x) for frame in curves.values() for x in frame["x"]})
        ax.set_xticks(ticks, [f"{x:g}" for x in ticks])
        ax.minorticks_off()
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(textwrap.fill(title, CURVE_TITLE_CHARS), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return fitted_png(fig)


BAR_LABEL = {"rmse": "RMSE"}
MIN_BAR_ROWS = 3      # estimator_bars: a panel at least this many groups high


@gc_paused
def estimator_bars(panels: dict[str, dict[str, dict[str, tuple[float, float, float]]]], unit: str = "m") -> bytes:
    """Grouped horizontal bars, one panel per title (a scenario), one group per label (an
    estimator cell) and one bar per statistic: its value with the 95% interval as an error bar
    where there is one (panels: title -> label -> statistic -> (value, low, high)). A value
    that is not finite is left out, with "(not finite)" after the label."""
    groups = max([len(labels) for labels in panels.values()] + [MIN_BAR_ROWS])   # the legend below needs the room
    fig, axes = plt.subplots(1, len(panels), figsize=(5.4 * len(panels), 0.9 + 0.42 * groups * 1.6), squeeze=False)
    for ax, (title, labels) in zip(axes[0], panels.items()):
        names = list(dict.fromkeys(stat for stats in labels.values() for stat in stats))
        height = 0.8 / max(1, len(names))
        for k, stat in enumerate(names):
            rows = [labels[label].get(stat, (np.nan,) * 3) for label in labels]
            value, low, high = (np.array(column, dtype=float) for column in zip(*rows)) if rows else ([],) * 3
            shown = np.isfinite(value)
            y = np.arange(len(labels)) + (k - (len(names) - 1) / 2) * height
            error = np.vstack([value - low, high - value])
            error = np.where(np.isfinite(error), error, 0.0)
            ax.barh(y[shown], value[shown], height=height * 0.95, label=BAR_LABEL.get(stat, stat),
                    xerr=error[:, shown], error_kw={"elinewidth": 0.8, "capsize": 2, "ecolor": "0.2"})
        ticks = [label + ("" if all(np.isfinite(v[0]) for v in labels[label].values()) else " (not finite)")
                 for label in labels]
        ax.set_yticks(np.arange(len(labels)), ticks, fontsize=8)
        ax.invert_yaxis()
        ax.set_xlabel(f"position error [{unit}]")
        ax.set_title(title, fontsize=10)
        ax.grid(axis="x", alpha=0.3)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16 - 0.35 / groups),
                  ncols=len(names), frameon=False)        # below the axes: never over a bar
    return fitted_png(fig)


@gc_paused
def ranging_validation(curves: dict[str, dict[str, pd.DataFrame]]) -> bytes:
    """Two panels, median signed range error and p95 |error| (m) against the true distance (m,
    log axis, each point at its bin's geometric centre): one line per source label, each frame
    with columns x, value, ci95_low, ci95_high (error bars where an interval exists). curves:
    {panel title: {label: frame}}; NLOS labels dashed."""
    fig, axes = plt.subplots(1, len(curves), figsize=(9.0, 3.8), squeeze=False)
    handles = {}
    for ax, (title, lines) in zip(axes[0], curves.items()):
        for k, (label, frame) in enumerate(lines.items()):
            low, high = frame["ci95_low"].to_numpy(float), frame["ci95_high"].to_numpy(float)
            value = frame["value"].to_numpy(float)
            yerr = np.vstack([value - low, high - value]) if np.isfinite(low).any() else None
            handle = ax.errorbar(frame["x"], value, yerr=yerr, marker="os^vD<>"[k % 7], ms=4, capsize=2, lw=1.2,
                                 ls="--" if "NLOS" in label else "-", color=f"C{k}", label=label)
            handles.setdefault(label, handle)
        ax.set_xscale("log")
        ax.set_xlabel("true distance [m]")
        ax.set_ylabel(f"{title} [m]")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=3, fontsize=7,
               bbox_to_anchor=(0.5, -0.02), frameon=False)
    fig.tight_layout(rect=(0, 0.16, 1, 1))
    return to_png(fig)
