"""Figures of the bounds section: CRLB / GDOP maps on the floor, sqrt(PCRB) beside the RMSE,
ANEES / ANIS with their chi-square band. Each function returns PNG bytes."""

from __future__ import annotations

import os
import re
import textwrap

import matplotlib as mpl
import numpy as np
import pandas as pd
from matplotlib.collections import LineCollection
from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator, StrMethodFormatter
from matplotlib.transforms import ScaledTranslation
from mpl_toolkits.axes_grid1 import make_axes_locatable

from wsnloc.campaign import Campaign
from wsnloc.metrics.consistency import ConsistencyTest
from wsnloc.report.figures import LABEL_OFFSET, PNG_DPI, TECH_STYLE, draw_walls, gc_paused, placeholder, plt, to_png

LEGEND_DROP_IN = 0.45      # inches from the bottom of the axes to the legend, below tick labels and x label
TITLE_WRAP_CHARS = 90      # a 9 pt title line of this many characters fits the 8 in wide figure


def _finish_time_axes(ax, ylabel: str, title: str, columns: int = 2) -> int:
    """Labels, grid, plain tick numbers and the legend below the axes (clear of the curves),
    in `columns` columns; returns its number of rows."""
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.yaxis.set_major_formatter(StrMethodFormatter("{x:g}"))
    low, high = ax.get_ylim()   # minor labels only within a decade (more would overlap)
    if high < 10 * low:
        ax.yaxis.set_minor_formatter(FuncFormatter(_minor_log_label))
        ax.tick_params(axis="y", which="minor", labelsize=7)
    else:
        _minor_log_grid(ax, low, high)
    below = ScaledTranslation(0.0, -LEGEND_DROP_IN, ax.figure.dpi_scale_trans)
    legend = ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, 0.0),
                       bbox_transform=ax.transAxes + below, ncol=columns, frameon=False)
    return -(-len(legend.legend_handles) // columns)


def _minor_log_label(value: float, _position=None) -> str:
    """Label of a minor log tick m x 10^k: the value for m in 2, 3, 5 only (at least
    log10(5/3) = 0.22 decade apart; m = 9 would touch the label of 10^(k+1))."""
    mantissa = value / 10.0 ** np.floor(np.log10(value))
    return f"{value:g}" if round(mantissa) in (2, 3, 5) else ""


def _minor_log_grid(ax, low: float, high: float) -> None:
    """The unlabelled minor grid of a log y axis (2..9 x 10^k within [low, high]) as one
    LineCollection instead of minor ticks (three artists each, re-laid out on every draw)."""
    ax.yaxis.set_minor_locator(NullLocator())
    levels = LogLocator(subs=np.arange(2, 10)).tick_values(low, high)
    levels = levels[(levels >= low) & (levels <= high)]
    grid = LineCollection([[(0.0, y), (1.0, y)] for y in levels], transform=ax.get_yaxis_transform(),
                          colors=mpl.rcParams["grid.color"], linewidths=mpl.rcParams["grid.linewidth"],
                          alpha=0.3, zorder=1.5)
    ax.add_collection(grid, autolim=False)


def _overlay_floor(ax, campaign: Campaign, anchors: pd.DataFrame) -> None:
    """Walls, the path and the given anchors (with ids) over a map."""
    draw_walls(ax, campaign.walls, color="w", lw=1.6)
    if campaign.path is not None:
        pose = campaign.path.evaluate(np.linspace(0, campaign.path.length, 400))
        ax.plot(pose["x"], pose["y"], color="tab:orange", lw=1.8, label="path")
    for tech, group in anchors.groupby("tech"):
        color, marker = TECH_STYLE.get(tech, ("tab:gray", "D"))
        ax.scatter(group["x"], group["y"], c=color, marker=marker, s=40, edgecolors="w", zorder=3,
                   label=f"{tech} ({len(group)})")
        for _, a in group.iterrows():   # co-located anchors of two technologies: labels above / below
            ax.annotate(a["anchor_id"], (a["x"], a["y"]), xytext=LABEL_OFFSET.get(tech, (4, 3)),
                        textcoords="offset points", fontsize=7, color="w")


@gc_paused
def bound_maps(campaign: Campaign, anchors: pd.DataFrame | dict[str, pd.DataFrame], x, y,
               panels: dict[str, np.ndarray]) -> bytes:
    """One floor map per panel (title with units -> values (len(y), len(x)) on the grid of
    cell centres x, y in m), with the anchors drawn (one frame, or one per panel title). The
    colour scale runs from the minimum to the 95th percentile (values above are drawn in the
    top colour); infinite values (singular geometry) are grey. Saved as an indexed PNG: the
    colour map has 256 entries itself, so 256 colours show it without visible banding, at a
    third of the bytes of 24-bit RGB."""
    width, height = campaign.spec["floor"]["width_m"], campaign.spec["floor"]["height_m"]
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, (9 * height / width + 0.9) * len(panels)), squeeze=False)
    for ax, (title, values) in zip(axes[:, 0], panels.items()):
        finite = values[np.isfinite(values)]
        low, high = (finite.min(), np.percentile(finite, 95)) if finite.size else (0.0, 1.0)
        cmap = plt.get_cmap("viridis").with_extremes(bad="0.6")
        image = ax.pcolormesh(x, y, np.ma.masked_invalid(values), cmap=cmap, shading="nearest", vmin=low, vmax=high)
        fig.colorbar(image, cax=make_axes_locatable(ax).append_axes("right", size="2.5%", pad=0.1),
                     label=title.split(": ", 1)[-1].split(" (")[0], extend="max")   # quantity [unit]
        _overlay_floor(ax, campaign, anchors[title] if isinstance(anchors, dict) else anchors)
        ax.set_xlim(0, width)
        ax.set_ylim(0, height)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f"{campaign.name}: {title}", fontsize=10, pad=14)   # clear of labels of anchors on the edge
        ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.12), ncol=3, fontsize=7, frameon=False)
    return to_png(fig)


def _draw_pcrb(ax, t, rmse: dict[str, np.ndarray], sqrt_pcrb: np.ndarray, bound_model: str, title: str) -> int:
    """RMSE curves (m) of one or more estimators over t (s) and the sqrt(PCRB) (m) they share;
    returns the rows of the legend."""
    for label, values in rmse.items():
        ax.plot(t, values, lw=1.2, label=f"{label} RMSE")
    ax.plot(t, sqrt_pcrb, color="k", lw=1.8, ls="--", label="sqrt(PCRB)")
    ax.set_yscale("log")
    return _finish_time_axes(ax, "position error [m]",
                             f"{title}\n" + textwrap.fill(f"bound for: {bound_model}", TITLE_WRAP_CHARS))


def _draw_consistency(ax, t, tests: dict[str, ConsistencyTest], statistic: str, title: str) -> int:
    """The statistic (ANEES or ANIS) of one or more estimators (label -> test, all with the
    same 95% band over t in s) and each one's time average as a horizontal line (one
    estimator: red; several: dotted, of the curve's colour), that average with its band and
    verdict in the legend. Returns the rows of the legend."""
    band = next(iter(tests.values()))
    ax.fill_between(t, band.low, band.high, color="tab:green", alpha=0.25, lw=0, label="95% band")
    for k, (label, test) in enumerate(tests.items()):
        average = (f"time average {test.time_average:.2f} "
                   f"(band {test.time_low:.2f}-{test.time_high:.2f}): {test.verdict}")
        if len(tests) == 1:
            ax.plot(t, test.average, color="tab:blue", lw=1.0, label=statistic)
            ax.axhline(test.time_average, color="tab:red", lw=1.2, label=average)
        else:
            line, = ax.plot(t, test.average, color=f"C{k}", lw=1.0, label=f"{label}: {average}")
            ax.axhline(test.time_average, color=line.get_color(), lw=1.2, ls=":")
    ax.set_yscale("log")
    return _finish_time_axes(ax, statistic, title, columns=2 if len(tests) == 1 else 1)


def _label_parts(titles: list[str]) -> tuple[str, list[str], str]:
    """Titles of panels that differ only in their cell's name, split into the common head (up
    to ": " or ", "), each title's own middle and the common tail (from a space or comma):
    ("s: ekf [all]", "s: ukf [all]") -> ("s: ", ["ekf", "ukf"], " [all]"),
    ("s: P, 10 runs", "s: PV, 10 runs") -> ("s: ", ["P", "PV"], ", 10 runs"). One title:
    (title, [""], "")."""
    if len(titles) == 1:
        return titles[0], [""], ""
    head = os.path.commonprefix(titles)
    cut = max(head.rfind(": "), head.rfind(", "))
    head = head[:cut + 2] if cut >= 0 else ""
    tail = os.path.commonprefix([title[len(head):][::-1] for title in titles])[::-1]
    separator = re.search(r"[ ,]", tail)
    tail = tail[separator.start():] if separator else ""
    return head, [title[len(head):len(title) - len(tail)] for title in titles], tail


def _same(a, b) -> bool:
    """Equal arrays (NaN equal to NaN, up to rounding)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=1e-9, atol=0.0, equal_nan=True))


def _runs(panels: list[tuple], shared) -> list[list[tuple]]:
    """Consecutive panels grouped while shared(the group so far, panel) holds."""
    groups = []
    for panel in panels:
        if groups and shared(groups[-1], panel):
            groups[-1].append(panel)
        else:
            groups.append([panel])
    return groups


def merged_pcrb_panels(panels: list[tuple]) -> list[tuple]:
    """Consecutive pcrb panels (t, rmse, sqrt_pcrb, bound_model, title) with the same time
    grid, bound model and sqrt(PCRB) (cells of one scenario whose bound is the same) as one
    panel: all their RMSE curves beside the one bound, under a title naming every cell. A panel
    whose curve label is already in the group (the same estimator in another table or subset)
    starts a panel of its own, so that no curve is hidden under another's label."""
    def shared(group, b):
        a = group[0]
        return (a[3] == b[3] and _same(a[0], b[0]) and _same(a[2], b[2])
                and not any(label in panel[1] for panel in group for label in b[1]))

    merged = []
    for group in _runs(panels, shared):
        head, names, tail = _label_parts([panel[4] for panel in group])
        rmse = {label: values for panel in group for label, values in panel[1].items()}
        t, _, sqrt_pcrb, bound_model, _ = group[0]
        merged.append((t, rmse, sqrt_pcrb, bound_model, head + ", ".join(names) + tail))
    return merged


def merged_consistency_panels(panels: list[tuple]) -> list[tuple]:
    """Consecutive consistency panels (t, test, statistic, title) of one statistic with the
    same time grid and 95% band (cells of one scenario with the same runs) as one panel of
    all their curves: (t, {cell name: test}, statistic, common title), the cell name being
    what sets a title apart from the others of its group ("s: ekf [all]", "s: ukf [all]" ->
    "s [all]"); a panel whose title is already in the group starts a panel of its own."""
    def shared(group, b):
        a = group[0]
        return (a[2] == b[2] and _same(a[0], b[0]) and _same(a[1].low, b[1].low) and _same(a[1].high, b[1].high)
                and all(panel[3] != b[3] for panel in group))

    merged = []
    for group in _runs(panels, shared):
        head, names, tail = _label_parts([panel[3] for panel in group])
        title = head.rstrip(" ,:") + tail if len(group) > 1 else head
        merged.append((group[0][0], dict(zip(names, (panel[1] for panel in group))), group[0][2], title))
    return merged


STACK_PAD_IN = 0.08       # inches between a panel's decorations and the edge of its slot
LEGEND_ROW_IN = 0.16      # inches a 7 pt legend row takes (its text and spacing)


def _stacked(draw, panels: list[tuple], height: float) -> bytes:
    """One axes per panel (the arguments of draw after the axes; draw returns the rows of the
    legend), stacked vertically in slots of `height` inches plus LEGEND_ROW_IN per legend row
    beyond the second, laid out by _fit_slots (one measuring pass, no layout engine)."""
    fig, axes = plt.subplots(len(panels), 1, figsize=(8, height * len(panels)), squeeze=False)
    heights = [height + LEGEND_ROW_IN * max(0, draw(ax, *args) - 2) for ax, args in zip(axes[:, 0], panels)]
    fig.set_size_inches(8, sum(heights))
    _fit_slots(fig, list(axes[:, 0]), heights)
    return to_png(fig, tight=False)


def _fit_slots(fig, axes: list, heights: list[float]) -> None:
    """Axes i fills slot i (the i-th band from the top, heights[i] inches high) minus its
    decorations: margins m = tight bbox - axes box, measured once (inches); all axes share
    the left edge max(m_left) + pad and the right edge width - max(m_right) - pad, and
    axes i spans [slot bottom + m_below + pad, slot top - m_above - pad].
    The decorations do not scale with the axes (font sizes, legend offset in inches)."""
    fig.set_dpi(PNG_DPI)
    renderer = fig.canvas.get_renderer()
    width, total = fig.get_size_inches()
    margins = []
    for ax in axes:
        inner, outer = ax.get_window_extent(renderer), _decorated_box(ax, renderer)
        margins.append(np.array([inner.x0 - outer.x0, outer.x1 - inner.x1,
                                 inner.y0 - outer.y0, outer.y1 - inner.y1]) / fig.dpi)
    left = max(m[0] for m in margins) + STACK_PAD_IN
    right = width - max(m[1] for m in margins) - STACK_PAD_IN
    slot_top = total
    for ax, height, (_, _, below, above) in zip(axes, heights, margins):
        top = slot_top - above - STACK_PAD_IN
        bottom = slot_top - height + below + STACK_PAD_IN
        ax.set_position([left / width, bottom / total, (right - left) / width, (top - bottom) / total])
        slot_top -= height


def _decorated_box(ax, renderer):
    """Axes.get_tightbbox (pixels) of a time panel with its legend as the only extra artist.
    The default extras add the spines, on the axes' edges with their tick marks under the
    tick labels, and the axes patch (the axes box), both inside the union of the axes box
    and its tick labels (up to the last bit of a spine's transformed edge); each spine would
    lay out its axis' ticks once more."""
    return ax.get_tightbbox(renderer, bbox_extra_artists=[ax.get_legend()])


def pcrb_vs_rmse(t, rmse: dict[str, np.ndarray], sqrt_pcrb: np.ndarray, bound_model: str, title: str) -> bytes:
    """Monte Carlo RMSE curves (m) of estimators and sqrt(PCRB) (m) over time t (s).

    bound_model states the motion and noise model the bound assumes (printed under the title).
    """
    return pcrb_panels([(t, rmse, sqrt_pcrb, bound_model, title)])


@gc_paused
def pcrb_panels(panels: list[tuple]) -> bytes:
    """pcrb_vs_rmse for several cells (t, rmse, sqrt_pcrb, bound_model, title), one panel per
    run of cells that share the bound (merged_pcrb_panels)."""
    return _stacked(_draw_pcrb, merged_pcrb_panels(panels), 3.8)


def consistency_over_time(t, test: ConsistencyTest, statistic: str, title: str) -> bytes:
    """ANEES or ANIS (statistic names which) over time t (s) with its 95% band, and the time
    average with its band and the verdict in the legend."""
    return consistency_panels([(t, test, statistic, title)])


@gc_paused
def consistency_panels(panels: list[tuple]) -> bytes:
    """consistency_over_time for several cells and statistics (t, test, statistic, title), one
    panel per run of cells that share the band (merged_consistency_panels)."""
    return _stacked(_draw_consistency, merged_consistency_panels(panels), 3.6)


def bound_and_anees_figures(bound_panels: list[tuple], consistency: list[tuple],
                            none: str | None = None) -> tuple[bytes, bytes]:
    """The two bound figures of a paper or study: sqrt(PCRB) beside the RMSE (pcrb_panels) and,
    over time, the position ANEES (consistency_panels of the "ANEES" panels; the ANIS, with its
    band and verdict, is in the tables and results.csv). With `none` given, a figure without
    panels is a placeholder saying so."""
    anees = [panel for panel in consistency if panel[2] == "ANEES"]
    return (pcrb_panels(bound_panels) if bound_panels or none is None else placeholder(none),
            consistency_panels(anees) if anees or none is None else placeholder(none))
