"""Report figures: stacked time panels laid out without a layout engine, log minor grid and
labels, fitted grids saved as laid out (one measuring pass), tight figures cut from one draw;
the cheaper paths (walls as one collection, one tight-layout pass, panel boxes without
spines, collector paused) against the matplotlib calls they replace."""

import gc
import io

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import LineCollection
from matplotlib.layout_engine import TightLayoutEngine
from matplotlib.ticker import NullLocator
from matplotlib.transforms import Bbox
from PIL import Image

from wsnloc.metrics.consistency import consistency_test
from wsnloc.report import bound_figures, figures
from wsnloc.report.figures import OVERLAPS_KEY, PNG_DPI, plt, text_overlaps

LONG_MODEL = ("PV, white acceleration 0.3 m/s^2; Gaussian ranges sigma 0.3 m, log-normal RSS (the filter's "
              "path-loss model); anchors UWB=12+ZigBee=21; epoch updates every 0.5 s, static epochs frozen")


def stacked_figure(height: float = 3.8):
    """Three pcrb panels: a long bound model, errors within a decade, errors over three decades."""
    t = np.linspace(0.0, 100.0, 201)
    panels = [(t, {"EKF": 0.3 + 0.1 * np.sin(t)}, np.full_like(t, 0.2), LONG_MODEL, "newcom/constant: Table I"),
              (t, {"EKF": 0.15 + 0.05 * np.cos(t), "UKF": 0.12 + 0.0 * t}, np.full_like(t, 0.1), "P", "narrow"),
              (t, {"PF with a long estimator label": np.logspace(-2, 1, t.size)}, np.full_like(t, 0.05), "P", "wide")]
    fig, axes = plt.subplots(len(panels), 1, figsize=(8, height * len(panels)), squeeze=False)
    for ax, args in zip(axes[:, 0], panels):
        bound_figures._draw_pcrb(ax, *args)
    bound_figures._fit_slots(fig, list(axes[:, 0]), [height] * len(panels))
    return fig, list(axes[:, 0])


def test_stacked_panels_fill_their_slots_with_decorations_inside():
    height = 3.8
    fig, axes = stacked_figure(height)
    renderer = fig.canvas.get_renderer()
    width_px, total_px = fig.bbox.width, fig.bbox.height
    lefts = set()
    for i, ax in enumerate(axes):
        outer = ax.get_tightbbox(renderer)
        slot_top, slot_bottom = total_px - i * height * PNG_DPI, total_px - (i + 1) * height * PNG_DPI
        assert outer.x0 >= 0 and outer.x1 <= width_px, (i, outer)
        assert slot_bottom <= outer.y0 and outer.y1 <= slot_top, (i, outer, slot_bottom, slot_top)
        assert ax.bbox.height > 0.5 * height * PNG_DPI      # the axes keep most of the slot
        lefts.add(round(ax.bbox.x0, 6))
    assert len(lefts) == 1                                  # one left edge for all panels
    assert text_overlaps(fig) == []
    assert axes[0].get_title().count("\n") >= 2             # the long bound model is wrapped, not cut
    plt.close(fig)


def test_minor_log_labels_only_at_2_3_5():
    values = [0.09, 0.2, 0.3, 0.4, 0.5, 0.7, 2.0, 3.0, 9.0]
    assert [bound_figures._minor_log_label(v) for v in values] == ["", "0.2", "0.3", "", "0.5", "", "2", "3", ""]


def test_wide_log_axis_draws_its_minor_grid_as_one_collection():
    fig, axes = stacked_figure()
    wide, narrow = axes[2], axes[1]
    low, high = wide.get_ylim()
    expected = [m * 10.0 ** k for k in range(-4, 3) for m in range(2, 10) if low <= m * 10.0 ** k <= high]
    grids = [c for c in wide.collections if isinstance(c, LineCollection)]
    assert isinstance(wide.yaxis.get_minor_locator(), NullLocator) and len(grids) == 1
    assert np.allclose(sorted(seg[0][1] for seg in grids[0].get_segments()), expected)
    assert not isinstance(narrow.yaxis.get_minor_locator(), NullLocator)   # within a decade: labelled ticks
    plt.close(fig)


@pytest.mark.parametrize("panels", [1, 3])
def test_fitted_figures_are_saved_as_laid_out(panels):
    rng = np.random.default_rng(1)
    curves = {f"panel {i}": {"EKF": rng.gamma(2.0, 0.2, 500), "UKF": rng.gamma(2.0, 0.25, 500)} for i in range(panels)}
    png = figures.error_cdf(curves)
    image = Image.open(io.BytesIO(png))
    assert image.size == (round(5.2 * panels * PNG_DPI), round(3.8 * PNG_DPI))   # not cropped by a tight box
    assert image.mode == "P"                                                      # indexed colours
    assert image.text[OVERLAPS_KEY] == "[]"
    assert figures.error_cdf(curves) == png


def test_stacked_consistency_panels_record_no_overlaps():
    t = np.arange(200) * 0.5
    test = consistency_test(np.random.default_rng(0).chisquare(4, size=(10, 200)), 4)
    other = consistency_test(np.random.default_rng(1).chisquare(4, size=(6, 200)), 4)     # another band
    panels = [(t, test, "ANEES", f"site: cell {i} [all]") for i in range(4)] + [(t, other, "ANEES", "other")]
    png = bound_figures.consistency_panels(panels)
    image = Image.open(io.BytesIO(png))
    rows = 1 + 4                                      # the band, one line per cell (one column)
    height = (3.6 + bound_figures.LEGEND_ROW_IN * (rows - 2) + 3.6) * PNG_DPI     # two panels
    assert image.size[0] == 8 * PNG_DPI and abs(image.size[1] - height) < 1
    assert image.text[OVERLAPS_KEY] == "[]"


def test_cells_sharing_a_bound_or_band_share_a_panel():
    t = np.arange(20) * 0.5
    bound = np.full(20, 0.2)
    panels = [(t, {"ekf": np.full(20, 0.3)}, bound, "PV", "site: ekf [all], 2 runs"),
              (t, {"ukf": np.full(20, 0.4)}, bound.copy(), "PV", "site: ukf [all], 2 runs"),
              (t, {"pf": np.full(20, 0.4)}, bound * 1.01, "PV", "site: pf [all], 2 runs"),     # its own bound
              (t, {"tracker": np.full(20, 0.4)}, bound, "P", "site: tracker [all], 2 runs")]  # another model
    merged = bound_figures.merged_pcrb_panels(panels)
    assert [p[4] for p in merged] == ["site: ekf, ukf [all], 2 runs", "site: pf [all], 2 runs",
                                      "site: tracker [all], 2 runs"]
    assert list(merged[0][1]) == ["ekf", "ukf"] and merged[0][2] is bound
    test = consistency_test(np.random.default_rng(0).chisquare(2, size=(5, 20)), 2)
    anees = [(t, test, "ANEES", "site: ekf [all], 2 runs"), (t, test, "ANEES", "site: ukf [all], 2 runs"),
             (t, test, "ANIS", "site: ekf [all], 2 runs")]
    merged = bound_figures.merged_consistency_panels(anees)
    assert bound_figures._label_parts(["s: 6: B1..B6, P, 10 runs", "s: 6: B1..B6, PV, 10 runs"]) == \
        ("s: 6: B1..B6, ", ["P", "PV"], ", 10 runs")
    assert bound_figures._label_parts(["s: Table I, hybrid, 10 runs", "s: Table II, hybrid, 10 runs"]) == \
        ("s: ", ["Table I", "Table II"], ", hybrid, 10 runs")
    assert [(p[3], list(p[1]), p[2]) for p in merged] == [("site [all], 2 runs", ["ekf", "ukf"], "ANEES"),
                                                          ("site: ekf [all], 2 runs", [""], "ANIS")]


def test_the_same_estimator_in_two_tables_keeps_both_curves_under_one_bound():
    """Paper A's hybrid EKF in Table I and Table II: the same bound and the same curve label.
    Merged into one panel, one curve would hide under the other's label; each keeps a panel."""
    t = np.arange(20) * 0.5
    bound = np.full(20, 0.2)
    first, second = np.full(20, 0.3), np.full(20, 0.5)
    panels = [(t, {"hybrid": first}, bound, "PV", "s: Table I, hybrid, 10 runs"),
              (t, {"hybrid": second}, bound, "PV", "s: Table II, hybrid, 10 runs")]
    merged = bound_figures.merged_pcrb_panels(panels)
    assert [(p[4], p[1]["hybrid"][0]) for p in merged] == [("s: Table I, hybrid, 10 runs", 0.3),
                                                           ("s: Table II, hybrid, 10 runs", 0.5)]
    test = consistency_test(np.random.default_rng(0).chisquare(2, size=(5, 20)), 2)
    same_title = [(t, test, "ANEES", "s: ekf [all]"), (t, test, "ANEES", "s: ekf [all]")]
    assert len(bound_figures.merged_consistency_panels(same_title)) == 2



def test_bound_and_anees_figures_keep_the_anees_panels_and_say_when_there_are_none():
    t = np.arange(50) * 0.5
    test = consistency_test(np.random.default_rng(1).chisquare(2, size=(5, 50)), 2)
    panels = [(t, test, "ANEES", "cell: ANEES"), (t, test, "ANIS", "cell: ANIS")]
    bound = [(t, {"ekf": np.full(50, 0.3)}, np.full(50, 0.2), "PV", "cell")]
    pcrb_png, anees_png = bound_figures.bound_and_anees_figures(bound, panels)
    assert pcrb_png == bound_figures.pcrb_panels(bound)
    assert anees_png == bound_figures.consistency_panels(panels[:1])          # the ANIS panel left out
    empty = bound_figures.bound_and_anees_figures([], [panels[1]], none="no filter here")
    assert empty == (figures.placeholder("no filter here"),) * 2

def test_long_curve_title_is_wrapped_inside_the_figure(monkeypatch):
    saved = {}
    monkeypatch.setattr(figures, "to_png", lambda fig, tight=True: saved.setdefault("fig", fig) and b"")
    title = "Paper C: RMSE against the a-priori noise, cricket/speed_20 (first runs; PVA: assumed IMU)"
    frame = {"x": [0.5, 1.0, 2.0], "value": [0.2, 0.2, 0.3], "ci95_low": [0.1] * 3, "ci95_high": [0.4] * 3}
    figures.curve_with_interval({"P": pd.DataFrame(frame)}, "factor", "RMSE [m]", title)
    fig = saved["fig"]
    fig.draw_without_rendering()
    box = fig.axes[0].title.get_window_extent()
    assert 0 <= box.x0 and box.x1 <= fig.bbox.width and "\n" in fig.axes[0].get_title()
    plt.close(fig)


def test_palette_png_keeps_the_rendered_colours():
    fig, _ = stacked_figure()
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    buffer = io.BytesIO()
    figures._save_palette_png(rgba, buffer)
    plt.close(fig)
    image = Image.open(io.BytesIO(buffer.getvalue()))
    assert image.mode == "P" and image.size == (rgba.shape[1], rgba.shape[0])
    difference = np.abs(np.asarray(image.convert("RGB"), dtype=int) - rgba[..., :3].astype(int))
    assert difference.mean() < 2.0 and difference.max() <= 24, (difference.mean(), difference.max())   # of 255


def test_palette_png_keeps_a_white_background():
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot([0, 1], [0, 1])
    fig.canvas.draw()
    buffer = io.BytesIO()
    figures._save_palette_png(np.asarray(fig.canvas.buffer_rgba()), buffer)
    plt.close(fig)
    assert Image.open(buffer).convert("RGB").getpixel((0, 0)) == (255, 255, 255)


def busy_figure(legend_x: float = 0.9):
    """A floor-plan-like figure: a figure legend at legend_x (figure fraction; 0.9 reaches
    past the 5 in wide canvas), a colour bar with an extension, a suptitle, an annotation
    and a marker not clipped to the axes."""
    fig, ax = plt.subplots(figsize=(5, 3))
    points = ax.scatter([0, 1, 2], [0, 1, 4], c=[0, 1, 2], label="anchors")
    ax.plot([0, 2], [4, 0], label="path")
    ax.plot([2.4], [2.0], "k^", clip_on=False)                     # past the right edge of the axes
    ax.annotate("A01", (2, 4), xytext=(4, 3), textcoords="offset points", fontsize=7)
    fig.colorbar(points, ax=ax, label="walls", extend="max")
    ax.set(xlim=(0, 2), xlabel="x [m]", ylabel="y [m]", title="floor")
    fig.suptitle("a suptitle")
    fig.subplots_adjust(top=0.8)
    fig.legend(loc="upper left", bbox_to_anchor=(legend_x, 0.8), fontsize=7)
    return fig


def savefig_tight_pixels(fig) -> np.ndarray:
    """RGB of savefig with the padded tight box of matplotlib, its corners moved out to whole pixels."""
    fig.set_dpi(PNG_DPI)
    fig.draw_without_rendering()
    box = fig.get_tightbbox(fig.canvas.get_renderer()).padded(plt.rcParams["savefig.pad_inches"])
    snapped = Bbox([np.floor(np.asarray(box.p0) * PNG_DPI) / PNG_DPI, np.ceil(np.asarray(box.p1) * PNG_DPI) / PNG_DPI])
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=PNG_DPI, bbox_inches=snapped)
    plt.close(fig)
    return np.asarray(Image.open(buffer).convert("RGB"))


def draws_of(fig) -> list:
    """Records each draw of the figure (draw_event) in the list returned."""
    draws = []
    fig.canvas.mpl_connect("draw_event", lambda event: draws.append(event.renderer.width))
    return draws


@pytest.mark.parametrize("legend_x", [0.9, 1.5])      # past the canvas; past the canvas and its drawn margin
def test_tight_png_is_the_tight_box_of_savefig(legend_x):
    expected = savefig_tight_pixels(busy_figure(legend_x))
    fig = busy_figure(legend_x)
    draws = draws_of(fig)
    image = Image.open(io.BytesIO(figures.to_png(fig, palette=False)))
    assert image.mode == "RGB" and image.text[OVERLAPS_KEY] == "[]"
    assert np.array_equal(np.asarray(image), expected)
    assert len(draws) == (1 if legend_x < 1 else 2)             # drawn again only for what the margin missed
    assert image.size[0] > 5 * PNG_DPI                           # the legend past the canvas is kept


def test_tight_box_from_the_draw_is_matplotlibs():
    for fig in (busy_figure(), busy_figure(1.5)):
        fig.set_dpi(PNG_DPI)
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        _, boxes = figures._text_boxes(fig, renderer)
        assert np.allclose(figures._tight_box(fig, renderer, boxes).extents,
                           fig.get_tightbbox(renderer).extents, atol=0.5 / PNG_DPI)
        plt.close(fig)


def test_tight_png_records_overlaps_of_its_own_draw():
    fig, ax = plt.subplots(figsize=(4, 2))
    ax.text(0.1, 0.5, "left", transform=ax.transAxes)
    ax.text(0.12, 0.5, "right", transform=ax.transAxes)
    draws = draws_of(fig)
    image = Image.open(io.BytesIO(figures.to_png(fig)))
    assert image.mode == "P" and image.text[OVERLAPS_KEY] == '[["left", "right"]]' and len(draws) == 1


def test_error_histograms_draw_the_pixels_of_bar_histograms(monkeypatch):
    errors = {label: np.random.default_rng(seed).gamma(2.0, 0.2, 4000) for seed, label in enumerate(("P", "PV"))}
    stepped = figures.error_histograms(errors, "title")
    hist = plt.Axes.hist
    monkeypatch.setattr(plt.Axes, "hist", lambda self, *a, histtype=None, **k: hist(self, *a, histtype="bar", **k))
    bars = figures.error_histograms(errors, "title")
    pixels = [np.asarray(Image.open(io.BytesIO(png)).convert("RGB")) for png in (stepped, bars)]
    assert pixels[0].shape == pixels[1].shape and (pixels[0] == pixels[1]).all()


WALLS = [(0.0, 0.0, 10.0, 0.0), (10.0, 0.0, 10.0, 5.0), (0.0, 5.0, 4.0, 5.0), (5.0, 5.0, 10.0, 5.0),
         (0.0, 0.0, 0.0, 5.0), (2.0, 1.0, 6.5, 3.7)]     # a door gap and a diagonal wall


@pytest.mark.parametrize("walls, color, lw", [(WALLS, "0.25", 2.2), (WALLS, "w", 1.6)])
def test_walls_as_one_collection_draw_the_pixels_of_one_line_per_wall(walls, color, lw):
    def drawn(draw) -> tuple:
        fig, ax = plt.subplots(figsize=(5, 3))
        ax.set_facecolor("tab:blue")
        ax.plot([5.0, 5.0], [-1.0, 6.0], color="tab:green", lw=3.0)        # drawn under the walls
        draw(ax)
        ax.plot([1.0, 9.0], [2.5, 2.5], color="tab:orange", lw=1.8)       # drawn over the walls
        ax.set_aspect("equal")
        fig.set_dpi(PNG_DPI)
        fig.canvas.draw()
        pixels = np.asarray(fig.canvas.buffer_rgba()).copy()
        limits = (ax.get_xlim(), ax.get_ylim())
        plt.close(fig)
        return pixels, limits

    def one_line_per_wall(ax) -> None:   # the former code
        for x1, y1, x2, y2 in walls:
            ax.plot([x1, x2], [y1, y2], color=color, lw=lw, solid_capstyle="butt")

    collection, lines = drawn(lambda ax: figures.draw_walls(ax, walls, color, lw)), drawn(one_line_per_wall)
    assert collection[1] == lines[1]                                         # autoscaled alike
    assert np.array_equal(collection[0], lines[0])


def test_no_walls_add_nothing():
    fig, ax = plt.subplots()
    figures.draw_walls(ax, [], "0.25", 2.2)
    fig.canvas.draw()
    assert not ax.collections and ax.get_xlim() == (0.0, 1.0)   # an empty collection would autoscale to +-0.055
    plt.close(fig)


def grid_figure():
    """A 2 x 2 grid with titles, labels, legends and a suptitle, for the tight layout."""
    fig, axes = plt.subplots(2, 2, figsize=(8, 5))
    for k, ax in enumerate(axes.flat):
        ax.plot(np.arange(10) * 10.0 ** k, label=f"curve {k}")
        ax.set(title=f"panel {k}", xlabel="x [m]", ylabel=f"quantity {k} [m]")
        ax.legend(fontsize=7)
    fig.suptitle("a grid")
    return fig


def test_one_tight_layout_pass_lays_out_as_the_default_engine():
    default, single = grid_figure(), grid_figure()
    for fig in (default, single):
        fig.set_dpi(PNG_DPI)
    TightLayoutEngine().execute(default)                       # measures the axes twice
    expected = [ax.get_position().extents for ax in default.axes]
    png = figures.to_png(default, tight=False)
    assert figures.fitted_png(single) == png
    assert np.allclose([ax.get_position().extents for ax in single.axes], expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("kind", ["pcrb", "consistency"])
def test_panel_box_without_spines_is_matplotlibs_tight_box(kind):
    if kind == "pcrb":
        fig, axes = stacked_figure()
    else:
        t = np.arange(200) * 0.5
        test = consistency_test(np.random.default_rng(0).chisquare(4, size=(10, 200)), 4)
        fig, axes = plt.subplots(2, 1, figsize=(8, 7.2), squeeze=False)
        axes = list(axes[:, 0])
        for ax in axes:
            bound_figures._draw_consistency(ax, t, {"": test}, "ANEES", "cell")
        fig.set_dpi(PNG_DPI)
    renderer = fig.canvas.get_renderer()
    for ax in axes:
        assert np.allclose(bound_figures._decorated_box(ax, renderer).extents, ax.get_tightbbox(renderer).extents,
                           rtol=0, atol=1e-9)                # pixels; a spine's edge may differ in the last bit
    plt.close(fig)


def test_figures_are_built_with_the_collector_paused():
    states = []
    build = figures.gc_paused(lambda: states.append(gc.isenabled()) or b"png")
    assert gc.isenabled() and build() == b"png" and states == [False] and gc.isenabled()
    with pytest.raises(ZeroDivisionError):
        figures.gc_paused(lambda: 1 / 0)()
    assert gc.isenabled()                                      # restored after a failure
    gc.disable()
    try:
        build()
        assert not gc.isenabled()                              # a caller's disabled collector stays disabled
    finally:
        gc.enable()
    for module in (figures, bound_figures):
        for name in ("placeholder", "floor_plan", "error_cdf", "trajectories", "error_over_time", "rmse_vs_anchors",
                     "error_histograms", "curve_with_interval", "bound_maps", "pcrb_panels", "consistency_panels"):
            if hasattr(module, name):
                assert hasattr(getattr(module, name), "__wrapped__"), name
