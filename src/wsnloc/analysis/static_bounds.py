"""Static CRLB / GDOP maps of a campaign's floor and the anchor-subset search, for the anchor
subsets a configuration uses (metrics.bounds, metrics.subset_search).

A subset expression ('all', or campaign subset names joined by '+', as the estimators read
them) splits into ranging anchors (every technology except ZigBee: UWB and Cricket give
ranges) and RSS anchors (ZigBee). Its bound is the TOA CRLB (ranges only), the RSS CRLB (RSS
only) or the hybrid CRLB (both; informations add), with the noise model `NoiseModel` of the
dataset (range sigma in m; path-loss exponent n and shadowing sigma in dB), 3-D ranges where
the anchors have a height (dz = anchor height - tag height). GDOP = TOA CRLB with sigma 1 m.
Along the path: the campaign path sampled at PATH_POINTS points equally spaced in arc length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError, WsnlocError
from wsnloc.estimators.run_data import ALL_ANCHORS
from wsnloc.metrics.bounds import (gdop, grid_points, hybrid_crlb, rss_crlb, rss_information_terms, toa_crlb,
                                   toa_information_terms)
from wsnloc.metrics.subset_search import rank_subsets

PATH_POINTS = 400
RSS_TECH = "zigbee"
EXPERIMENT = "bounds"


@dataclass(frozen=True)
class NoiseModel:
    """The measurement model of the static bounds of one dataset (config `bounds.models`)."""

    range_sigma_m: float
    path_loss_exponent: float | None = None
    sigma_db: float | None = None

    def describe(self, kind: str) -> str:
        toa = f"ranges sigma {self.range_sigma_m:g} m"
        if kind == "toa":
            return toa
        rss = f"RSS n {self.path_loss_exponent:g}, sigma {self.sigma_db:g} dB"
        return rss if kind == "rss" else f"{toa} + {rss}"


def members(campaign: Campaign, expression: str) -> tuple[list[str], list[str]]:
    """(ranging anchor ids, RSS anchor ids) of a subset expression, in campaign order."""
    if expression == ALL_ANCHORS:
        chosen = set(campaign.anchors["anchor_id"])
    else:
        subsets = campaign.spec.get("subsets", {})
        unknown = [name for name in expression.split("+") if name not in subsets]
        if unknown:
            raise ConfigError(f"anchor subset {unknown[0]!r} is not defined in {campaign.source}")
        chosen = {a for name in expression.split("+") for a in subsets[name]}
    anchors = campaign.anchors[campaign.anchors["anchor_id"].isin(chosen)]
    rss = anchors["tech"] == RSS_TECH
    return list(anchors.loc[~rss, "anchor_id"]), list(anchors.loc[rss, "anchor_id"])


def _geometry(campaign: Campaign, ids: list[str]) -> tuple[np.ndarray, np.ndarray | None]:
    """(anchor x, y (m), height offsets dz (m) or None for 2-D ranges)."""
    rows = campaign.anchors.set_index("anchor_id").loc[ids]
    z = rows["z"].to_numpy(float)
    dz = z - (campaign.tag_height_m or 0.0) if np.isfinite(z).any() else None
    return rows[["x", "y"]].to_numpy(float), None if dz is None else np.nan_to_num(dz)


def _need_rss(model: NoiseModel, expression: str) -> None:
    if model.path_loss_exponent is None or model.sigma_db is None:
        raise ConfigError(f"config key 'bounds.models': subset {expression!r} has RSS anchors; "
                          f"give path_loss_exponent and sigma_db")


def crlb(campaign: Campaign, expression: str, model: NoiseModel, points: np.ndarray) -> tuple[str, np.ndarray]:
    """(kind toa / rss / hybrid, position bound (m) at the points) of a subset expression."""
    toa_ids, rss_ids = members(campaign, expression)
    if rss_ids:
        _need_rss(model, expression)
    if toa_ids and rss_ids:
        (toa_xy, dz), (rss_xy, _) = _geometry(campaign, toa_ids), _geometry(campaign, rss_ids)
        return "hybrid", hybrid_crlb(points, toa_xy, model.range_sigma_m, rss_xy, model.path_loss_exponent,
                                     model.sigma_db, dz)
    if rss_ids:
        return "rss", rss_crlb(points, _geometry(campaign, rss_ids)[0], model.path_loss_exponent, model.sigma_db)
    xy, dz = _geometry(campaign, toa_ids)
    return "toa", toa_crlb(points, xy, model.range_sigma_m, dz)


def path_points(campaign: Campaign) -> np.ndarray:
    """(PATH_POINTS, 2) points of the campaign path (m), equally spaced in arc length."""
    if campaign.path is None:
        raise ConfigError(f"{campaign.source}: the static bounds along the path need a 'path'")
    pose = campaign.path.evaluate(np.linspace(0.0, campaign.path.length, PATH_POINTS))
    return np.column_stack([pose["x"], pose["y"]])


def distinct(campaign: Campaign, expressions: list[str]) -> list[str]:
    """The expressions without those naming the same anchors as an earlier one (e.g. 'all'
    after the subset of every anchor)."""
    seen, out = set(), []
    for expression in expressions:
        key = tuple(map(tuple, members(campaign, expression)))
        if key not in seen:
            seen.add(key)
            out.append(expression)
    return out


def floor_maps(campaign: Campaign, expressions: list[str], model: NoiseModel, spacing_m: float
               ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], dict[str, pd.DataFrame]]:
    """Grid x (nx,), y (ny,) (m), map panels (title -> (ny, nx) values) and the anchors of each
    panel: per distinct subset expression, the GDOP of a ranging-only subset (its CRLB is
    sigma x GDOP, said in the title) and the CRLB (m) of an RSS or hybrid one."""
    floor = campaign.spec["floor"]
    x, y, points = grid_points(floor["width_m"], floor["height_m"], spacing_m)
    panels, anchors = {}, {}
    for expression in distinct(campaign, expressions):
        toa_ids, rss_ids = members(campaign, expression)
        if rss_ids:
            kind, values = crlb(campaign, expression, model, points)
            title = f"{expression}: {kind.upper()} CRLB [m] ({model.describe(kind)})"
        else:
            xy, dz = _geometry(campaign, toa_ids)
            values = gdop(points, xy, dz)
            title = f"{expression}: GDOP [1] (TOA CRLB = {model.range_sigma_m:g} m x GDOP)"
        panels[title] = values.reshape(len(y), len(x))
        anchors[title] = campaign.anchors[campaign.anchors["anchor_id"].isin(toa_ids + rss_ids)]
    return x, y, panels, anchors


def path_rows(campaign: Campaign, expressions: list[str], model: NoiseModel, dataset: str) -> list[dict]:
    """results rows: mean and max CRLB (m) along the path of each subset expression."""
    points = path_points(campaign)
    out = []
    for expression in distinct(campaign, expressions):
        kind, values = crlb(campaign, expression, model, points)
        for statistic, value in (("mean", np.mean(values)), ("max", np.max(values))):
            out.append(results.single_row(float(value), experiment=EXPERIMENT, table="CRLB along the path",
                                          row=f"{expression} ({kind})", column=statistic, scenario=dataset,
                                          metric=f"crlb_{statistic}_m"))
    return out


def subset_search(campaign: Campaign, tech: str, k: int, model: NoiseModel) -> tuple[pd.DataFrame, dict[str, str]]:
    """All C(N, k) subsets of one technology's anchors ranked by mean CRLB along the path
    (subset_search.rank_subsets), and the campaign subsets of that technology with k anchors
    (e.g. the papers' UWB=9): name -> their `members` key in the table."""
    anchors = campaign.anchors_of(tech)
    if len(anchors) == 0:
        raise ConfigError(f"config key 'bounds.subset_sizes': {campaign.source} has no {tech!r} anchors")
    ids = list(anchors["anchor_id"])
    points = path_points(campaign)
    xy, dz = _geometry(campaign, ids)
    if tech == RSS_TECH:
        _need_rss(model, tech)
        terms = rss_information_terms(points, xy, model.path_loss_exponent, model.sigma_db)
    else:
        terms = toa_information_terms(points, xy, model.range_sigma_m, dz)
    table = rank_subsets(terms, ids, k)
    named = {name: ",".join(a for a in ids if a in subset) for name, subset in campaign.spec.get("subsets", {}).items()
             if len(subset) == k and set(subset) <= set(ids)}
    return table, named


def picked_subsets(table: pd.DataFrame, named: dict[str, str], shown: int) -> dict[str, str]:
    """Label -> members key of the subsets a search reports: the named ones, then the
    `shown` best and worst ('best 1: U01,...', 'worst 1: ...')."""
    picks = dict(named)
    picks.update({f"best {i + 1}: {key}": key for i, key in enumerate(table["members"].head(shown))})
    picks.update({f"worst {i + 1}: {key}": key for i, key in enumerate(table["members"].tail(shown)[::-1])})
    return picks


def search_label(tech: str, k: int, count: int) -> str:
    return f"subset search: {tech}, {k} anchors, {count} subsets"


def subset_rows(table: pd.DataFrame, named: dict[str, str], tech: str, k: int, dataset: str,
                shown: int) -> list[dict]:
    """results rows of a subset search: rank and mean CRLB along the path (m) of each picked
    subset (picked_subsets)."""
    label = search_label(tech, k, len(table))
    by_members = table.set_index("members")
    out = []
    for row, key in picked_subsets(table, named, shown).items():
        record = by_members.loc[key]
        out.append(results.single_row(int(record["rank"]), experiment=EXPERIMENT, table=label, row=row,
                                      column="rank", scenario=dataset, metric="rank"))
        out.append(results.single_row(float(record["mean_bound_m"]), experiment=EXPERIMENT, table=label, row=row,
                                      column="mean CRLB", scenario=dataset, metric="crlb_mean_m"))
    return out


def with_subsets(campaign: Campaign, subsets: dict[str, str]) -> Campaign:
    """The campaign with extra named subsets (label -> comma-joined anchor ids), so that an
    estimator can read any searched subset by its label (estimators' `anchors`)."""
    spec = dict(campaign.spec, subsets={**campaign.spec.get("subsets", {}),
                                        **{label: key.split(",") for label, key in subsets.items()}})
    return Campaign(name=campaign.name, format=campaign.format, spec=spec, source=campaign.source)


def monte_carlo_rows(campaign: Campaign, runs: dict[str, dict], label: str, dataset: str, tech: str, k: int,
                     model: NoiseModel, shown: int, estimator: dict) -> tuple[list[dict], list[str]]:
    """The picked subsets of one search run through a registry estimator on every run of a
    scenario (studies.run_cell; estimator: {estimator: name, parameter: value, ...}): results
    rows of the RMSE (m) per subset, mean over runs with its 95% interval (empty when the
    estimator gives no estimate on some run), and the reasons of those failures."""
    from wsnloc.estimators import registry
    from wsnloc.studies import run_cell

    table, named = subset_search(campaign, tech, k, model)
    picks = picked_subsets(table, named, shown)
    where = f"bounds.monte_carlo.estimators.{tech}"
    name = estimator.get("estimator", "tracker")
    p = registry.get(name, f"{where}.estimator").resolve({key: v for key, v in estimator.items()
                                                         if key != "estimator"}, where)
    extended = with_subsets(campaign, picks)
    out, failures = [], []
    for row in picks:
        try:
            rmse = run_cell(label, f"{tech} k={k}", name, p, [row], runs, extended)[1]["rmse"]
        except WsnlocError as error:   # e.g. collinear anchors: the initiator's multilateration never fixes
            failures.append(str(error))
            rmse = []
        out.append(results.row_over_runs(rmse, experiment=EXPERIMENT, table=search_label(tech, k, len(table)),
                                         row=row, column=f"RMSE {label}", scenario=dataset, metric="rmse_m"))
    return out, failures


def configured_subsets(config: dict, dataset: str) -> list[str]:
    """The subset expressions the configuration runs on a dataset (papers A and C, studies), in
    first-use order; 'all' when nothing names one."""
    from wsnloc.experiments import paper_c

    def on(spec) -> list[str]:
        return [label for label in (spec or {}).get("scenarios", []) if label.split("/", 1)[0] == dataset]

    out = []
    spec_a = config["experiments"].get("paper_a")
    if on(spec_a):
        out += [row["anchors"] for row in spec_a["rows"]]
    spec_c = config["experiments"].get("paper_c")
    for label in on(spec_c):
        out += paper_c.subsets_of(spec_c, label)
    for spec in (config.get("studies") or {}).values():
        if on(spec):
            out += spec.get("subsets") or [ALL_ANCHORS]
    return list(dict.fromkeys(out)) or [ALL_ANCHORS]


def monte_carlo_scenarios(config: dict) -> list[tuple[str, str]]:
    """(dataset, scenario) pairs of the opt-in subset Monte Carlo (config bounds.monte_carlo)."""
    return [tuple(label.split("/", 1)) for label in ((config.get("bounds") or {}).get("monte_carlo") or {})
            .get("scenarios", [])]


def check_config(config: dict) -> None:
    """`bounds.models` and `bounds.subset_sizes` name declared datasets; sizes need a model."""
    spec = config.get("bounds") or {}
    for key in ("models", "subset_sizes"):
        for dataset in spec.get(key) or {}:
            if dataset not in config["datasets"]:
                raise ConfigError(f"config key 'bounds.{key}.{dataset}': not a declared dataset "
                                  f"(declared: {', '.join(config['datasets'])})")
    for dataset in spec.get("subset_sizes") or {}:
        if dataset not in (spec.get("models") or {}):
            raise ConfigError(f"config key 'bounds.subset_sizes.{dataset}': needs 'bounds.models.{dataset}'")
    for label in (spec.get("monte_carlo") or {}).get("scenarios", []):
        dataset, scenario = label.split("/", 1)
        if scenario not in config["datasets"].get(dataset, {}).get("scenarios", []):
            raise ConfigError(f"config key 'bounds.monte_carlo.scenarios': {label!r} is not a declared dataset/scenario")
        if dataset not in (spec.get("subset_sizes") or {}):
            raise ConfigError(f"config key 'bounds.monte_carlo.scenarios': {label!r} needs 'bounds.subset_sizes.{dataset}'")
