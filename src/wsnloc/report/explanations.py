""""Why it differs": the look-ups behind the short explanations under each paper's tables of
its large differences from the paper (each paper's sentences: wsnloc.experiments.paper_x.report).
The sentences are written by hand; every number in them is read from the workflow's results
(results.csv rows), data summaries (data_summary.json) or the campaign files, and a sentence
whose numbers are missing (e.g. no NLOS links in the data) is left out.

Each RMSE cell outside our interval also gets an account of its gap (gap_account): the
contribution to our RMSE predicted by each mechanism that can be quantified from the build's
own numbers, their sum beside the gap, and the part the sum leaves unexplained.
"""

from __future__ import annotations

import functools
import math
import re

import pandas as pd

from wsnloc.analysis.setup_facts import BIAS_CALIBRATION, SETUP_TABLE
from wsnloc.campaign import Campaign
from wsnloc.experiments import claims as claims_of
from wsnloc.sim.imu import ACCEL_BIAS, bias_sigma


class Numbers:
    """Look-ups in results.csv rows and per-scenario data summaries; NaN when absent."""

    def __init__(self, results: pd.DataFrame, summaries: dict[str, dict], config: dict | None = None):
        self.results = results
        self.summaries = summaries
        self.config = config          # the workflow config: the scenarios' campaigns (campaign_of)

    def value(self, experiment: str, table: str, row: str, column: str, field: str = "value", **keys) -> float:
        """`field` of the first results row with these experiment, table, row, column and keys
        (columns of results.csv); NaN when there is none or it is missing. The rows of each
        key are indexed once (claims.cell_rows)."""
        match = {"experiment": experiment, "table": table, "row": row, "column": column, **keys}
        rows = claims_of.cell_rows(self.results, tuple(match)).get(tuple(match.values()))
        found = claims_of.column_values(self.results, field)[rows[0]] if rows is not None else math.nan
        return float(found) if pd.notna(found) else math.nan

    def fact(self, experiment: str, fact: str, scenario: str) -> float:
        return self.value(experiment, SETUP_TABLE, fact, scenario)

    def ranging(self, scenario: str) -> dict[str, float]:
        """NLOS share of the valid ranges and the NLOS / LOS median errors (m), pooled over runs."""
        pooled = self.summaries.get(scenario, {}).get("range_error_pooled", {})
        los, nlos = pooled.get("LOS", {}), pooled.get("NLOS", {})
        total = (los.get("n") or 0) + (nlos.get("n") or 0)
        return {"nlos_share": (nlos.get("n") or 0) / total if total else math.nan,
                "nlos_bias_m": _number(nlos.get("bias")), "los_median_m": _number(los.get("median")),
                "nlos_p95_m": _number(nlos.get("p95"))}

    def duration_s(self, scenario: str) -> float:
        """Mean run duration (s) of a scenario (data summary per run)."""
        return _mean([_number(r.get("duration_s")) for r in self.summaries.get(scenario, {}).get("per_run", [])])

    def imu_bias_sigma(self, scenario: str, key: str) -> float:
        """The per-run bias sigma of a scenario's simulated IMU by campaign key (sim.imu.bias_sigma:
        ACCEL_BIAS in m/s^2 per axis, GYRO_BIAS in deg/s; 0 under paper B's
        `snr` model); NaN without a campaign or a simulated IMU."""
        dataset, _, name = scenario.partition("/")
        if self.config is None or dataset not in self.config.get("datasets", {}):
            return math.nan
        campaign = campaign_of(self.config, scenario)
        if "imu" not in campaign.spec or name not in campaign.spec.get("scenarios", {}):
            return math.nan
        return bias_sigma(campaign, name, key)

    def rss_fit(self, scenario: str) -> dict[str, float]:
        """Path-loss fits over all links and over LOS links (mean over runs): exponent n and
        residual sigma (dB)."""
        runs = self.summaries.get(scenario, {}).get("per_run", [])
        values = {key: [_number(r.get(key)) for r in runs]
                  for key in ("fit_all_n", "fit_all_sigma_dB", "fit_los_n", "fit_los_sigma_dB")}
        return {key: _mean(v) for key, v in values.items()}


def _number(x) -> float:
    return float(x) if x is not None and not (isinstance(x, float) and math.isnan(x)) else math.nan


def _mean(values) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return sum(finite) / len(finite) if finite else math.nan


def finite(*values) -> bool:
    return all(not math.isnan(v) for v in values)


def ranging_severity(n: Numbers, experiment: str, cells: dict[str, str], reference: str) -> list[str]:
    """One sentence: mean RMSE of `cells` (text -> results row of table nlos_severity.TABLE)
    at every level of the UWB ranging severity sweep, then `reference` (a computed clause or "")."""
    from wsnloc.analysis.nlos_severity import TABLE

    sel = n.results[(n.results["experiment"] == experiment) & (n.results["table"] == TABLE)]
    levels = list(dict.fromkeys(sel["column"]))
    values = {(text, level): n.value(experiment, TABLE, row, level) for text, row in cells.items() for level in levels}
    if not levels or not finite(*values.values()):
        return []
    per_level = "; ".join(f"{level}: " + ", ".join(f"{text} {values[text, level]:.2f} m" for text in cells)
                          for level in levels)
    return [(f"Against UWB ranging severity (extra simulated runs of {sel['scenario'].iloc[0]}, RMSE per level): "
             f"{per_level}{reference}.")]


@functools.lru_cache(maxsize=None)
def _campaign(path: str) -> Campaign:
    """Campaign.load, once per file for all papers' sentences."""
    return Campaign.load(path)


def campaign_of(config: dict, label: str) -> Campaign:
    """The campaign of a dataset/scenario label (its scenario details: speed profile, speed)."""
    return _campaign(config["datasets"][label.split("/", 1)[0]]["campaign"])


# ---- one mechanism per table cell outside our interval ------------------------------------------
RANGING_WORDS = ("uwb", "toa", "range", "beacon", "beacons", "p", "pv", "pva", "min-max", "multilateration", "hybrid",
                 "mix", "f-mix", "p-mix", "fused", "fusion")
RSS_WORDS = ("rss", "zigbee", "narrowband", "hybrid", "mix")
DRIFT_WORDS = ("imu", "dead", "reckoning", "inertial", "kf", "fusion", "fused", "sskf")
STILL_SHARE = 0.05      # static share of epochs below which a run has no rest to measure sensor biases in


def _words(*labels: str) -> set[str]:
    """The lower-case words (letters, digits, inner hyphens) of `labels`."""
    return {w for label in labels for w in re.findall(r"[a-z0-9]+(?:-[a-z0-9]+)*", label.lower())}


SUBSET_FACT = re.compile(r"^(.*) \(([A-Za-z]+=[0-9]+)\)$")   # a set-up fact of one anchor subset: "<fact> (UWB=9)"


def bias_unmeasured(n: Numbers, experiment: str, scenario: str) -> bool:
    """Whether the dead reckoning of `scenario` has no measurement of its IMU biases: its run has
    no rest (static share below STILL_SHARE) or its estimator measures none (set-up fact
    BIAS_CALIBRATION = 0 s, whatever rests the run has)."""
    static, calibration = (n.fact(experiment, fact, scenario) for fact in ("static share of epochs", BIAS_CALIBRATION))
    return (finite(static) and static < STILL_SHARE) or calibration == 0.0


def cell_mechanism(n: Numbers, experiment: str, scenario: str, *labels: str) -> str:
    """The measured error sources behind one cell of `scenario`, chosen by the cell's kind (the
    words of its table title, row and column `labels`): the UWB / ultrasound ranging (NLOS share
    of the ranges, their median NLOS excess and LOS median error, m) for range-based cells, the
    RSS path-loss fit (exponent, residual spread in dB) for RSS cells, and the scenario's set-up
    facts (static share of epochs, anchors heard per epoch) for every cell, those of one anchor
    subset ("<fact> (UWB=9)") only for the cells that name it, in place of the unqualified one; "" when the build has
    none of these numbers for the scenario."""
    words = _words(*labels)
    parts = []
    r = n.ranging(scenario)
    if words & set(RANGING_WORDS) and finite(r["nlos_share"], r["los_median_m"]):
        parts.append(f"{r['nlos_share']:.0%} of the ranges are NLOS"
                     + (f" (median excess {r['nlos_bias_m']:.2f} m, a positive bias the estimators' range noise "
                        f"does not model)" if finite(r["nlos_bias_m"]) else "")
                     + f", LOS median range error {r['los_median_m']:.3f} m")
    fit = n.rss_fit(scenario)
    if words & set(RSS_WORDS) and finite(fit["fit_all_n"], fit["fit_all_sigma_dB"]):
        parts.append(f"RSS fits path-loss exponent n = {fit['fit_all_n']:.2f} with {fit['fit_all_sigma_dB']:.1f} dB "
                     f"residual spread (wall losses outside the RSS model)")
    facts = n.results[(n.results["experiment"] == experiment) & (n.results["table"] == SETUP_TABLE)
                      & (n.results["column"] == scenario)]
    subsets = set(re.findall(r"[A-Za-z]+=[0-9]+", " ".join(labels)))      # the cell's anchor subsets ("UWB=9")
    qualified = {m.group(1) for m in map(SUBSET_FACT.match, facts["row"]) if m}
    still = n.fact(experiment, "static share of epochs", scenario) < STILL_SHARE   # its note says it already
    for fact, value in zip(facts["row"], facts["value"]):
        subset = SUBSET_FACT.match(fact)
        if (subset.group(2) not in subsets) if subset else (fact in qualified and subsets):
            continue        # a fact of another subset, or the first subset's where the cell names its own
        drift = words & set(DRIFT_WORDS) and n.imu_bias_sigma(scenario, ACCEL_BIAS) != 0.0   # no bias: nothing to measure
        if fact == BIAS_CALIBRATION and not drift:
            continue
        if pd.notna(value):
            shown = f"{value:.0%}" if "share" in fact else f"{value:.1f}"
            note = ("no rest to measure the IMU biases in" if "static" in fact and value < STILL_SHARE else
                    "the biases are not measured" if fact == BIAS_CALIBRATION and value == 0.0 and not still else "")
            parts.append(f"{fact} {shown}" + (f" ({note}: dead reckoning integrates them)" if drift and note else ""))
    return "; ".join(parts)


DEAD_RECKONING_WORDS = ("dead", "reckoning")
FUSION_WORDS = ("fusion", "fused", "kf", "sskf", "mix", "hybrid")
GAP_WORDS = ("rmse", "max")     # tables whose cells get an account of their gap (m)


def contributions(n: Numbers, experiment: str, scenario: str, table: dict, row: str, value: float,
                  *labels: str) -> list[tuple[str, float]]:
    """(text with its arithmetic, predicted contribution in m) to our RMSE of one cell from each
    mechanism that the build's own numbers quantify, chosen by the cell's kind (its `labels`):

    - NLOS bias (range-based cells): a bias b (the NLOS ranges' median excess, m) on the share x
      of the ranges that are NLOS adds sqrt(x b^2) = sqrt(x) b (m) of RMS range error;
    - RSS wall losses (RSS cells): the log-normal model turns a spread of sigma dB around a
      path-loss exponent n into a relative range error eps = ln(10) sigma / (10 n); the links
      through walls (the fit over all links) against the LOS links' fit leave the share
      1 - eps_LOS / eps_all of a ranging-limited RMSE to the wall losses: RMSE (1 - eps_LOS / eps_all);
    - rests (cells whose results hold a moving-epoch RMSE, `<table> detail` / rmse_moving): the
      static epochs change our RMSE by RMSE - RMSE over the moving epochs (negative: rests help);
    - uncalibrated accelerometer bias (dead reckoning alone, its bias not measured: bias_unmeasured): a
      horizontal bias of RMS |b| = sqrt(2) sigma_b (sigma_b per axis, campaign) integrates to
      |b| t^2 / 2, whose RMS over a run of T s is |b| T^2 / (2 sqrt 5) and whose value at the
      run's end (a max error) is |b| T^2 / 2.
    None for other tables than RMSE and max-error ones."""
    words = _words(*labels)
    if not words & set(GAP_WORDS):
        return []
    out = []
    r = n.ranging(scenario)
    if words & set(RANGING_WORDS) and finite(r["nlos_share"], r["nlos_bias_m"]) and r["nlos_share"] > 0:
        x, b = r["nlos_share"], r["nlos_bias_m"]
        out.append((f"NLOS bias sqrt(x b^2) = sqrt({x:.3f} x {b:.3f}^2) = {math.sqrt(x) * b:+.3f} m",
                    math.sqrt(x) * b))
    fit = n.rss_fit(scenario)
    if (words & set(RSS_WORDS) and not words & set(RANGING_WORDS)
            and finite(fit["fit_all_n"], fit["fit_all_sigma_dB"], fit["fit_los_n"], fit["fit_los_sigma_dB"])):
        eps_all, eps_los = (math.log(10.0) * fit[f"fit_{k}_sigma_dB"] / (10.0 * fit[f"fit_{k}_n"])
                            for k in ("all", "los"))
        walls = value * (1.0 - eps_los / eps_all)
        out.append((f"RSS wall losses: ln(10) sigma / (10 n) = {eps_all:.3f} over all links "
                    f"({fit['fit_all_sigma_dB']:.2f} dB, n = {fit['fit_all_n']:.2f}) against {eps_los:.3f} "
                    f"on LOS links ({fit['fit_los_sigma_dB']:.2f} dB, "
                    f"n = {fit['fit_los_n']:.2f}), RMSE x (1 - {eps_los:.3f} / {eps_all:.3f}) = {walls:+.3f} m", walls))
    moving = n.value(experiment, f"{table['table']} detail", row, "rmse_moving", scenario=scenario) \
        if table.get("table") else math.nan
    if finite(moving):
        out.append((f"rests: RMSE - moving-epoch RMSE = {value:.3f} - {moving:.3f} = {value - moving:+.3f} m",
                    value - moving))
    sigma_b, duration = n.imu_bias_sigma(scenario, ACCEL_BIAS), n.duration_s(scenario)
    if (words & set(DEAD_RECKONING_WORDS) and not words & set(FUSION_WORDS) and finite(sigma_b, duration)
            and sigma_b > 0 and bias_unmeasured(n, experiment, scenario)):
        if "max" in words:
            drift = math.sqrt(2.0) * sigma_b * duration**2 / 2.0
            out.append((f"accelerometer bias not measured at rest, at the run's end: |b| T^2 / 2 with |b| = "
                        f"sqrt(2) x {sigma_b:g} m/s^2, T = {duration:.1f} s: {drift:+.3f} m", drift))
        else:
            drift = math.sqrt(2.0) * sigma_b * duration**2 / (2.0 * math.sqrt(5.0))
            out.append((f"accelerometer bias not measured at rest: |b| T^2 / (2 sqrt 5) with |b| = sqrt(2) x "
                        f"{sigma_b:g} m/s^2, T = {duration:.1f} s: {drift:+.3f} m", drift))
    return out


def drift_counterfactual(n: Numbers, experiment: str, scenario: str, value: float, others: dict[str, float],
                         *labels: str) -> list[tuple[str, float]]:
    """The IMU bias drift of a fused cell (its `labels` name a fusion) on a scenario whose IMU
    biases are not measured (bias_unmeasured): our value minus the same row's value on a scenario (`others`:
    scenario -> our value there) whose simulated IMU has no bias (the counterfactual without the
    drift), in m; [] without such a scenario."""
    words = _words(*labels)
    sigma_b = n.imu_bias_sigma(scenario, ACCEL_BIAS)
    if not (words & set(FUSION_WORDS) and words & set(GAP_WORDS) and finite(sigma_b) and sigma_b > 0
            and bias_unmeasured(n, experiment, scenario)):
        return []
    clean = next(((sc, v) for sc, v in others.items() if n.imu_bias_sigma(sc, ACCEL_BIAS) == 0.0 and finite(v)), None)
    if clean is None:
        return []
    sc, v = clean
    return [(f"IMU bias drift (the {sigma_b:g} m/s^2 turn-on bias not measured at rest; the same fusion on {sc}, "
             f"whose IMU has no bias, gives {v:.3f} m): {value:.3f} - {v:.3f} = {value - v:+.3f} m", value - v)]


def ranging_needed(ours: float, paper: float, explained: float, median_m: float) -> str:
    """Where we are below the paper and the rest of the gap is the paper's side: a ranging-limited
    position error scales with the range error, so the paper's value less the terms already
    explained (`explained`, m) needs ranges k = (paper + explained) / ours times less accurate
    than ours (median range error `median_m`): an extra independent error of
    sqrt(k^2 - 1) x median_m (m, median) that our data lack."""
    k = (paper + explained) / ours
    if not finite(k, median_m) or k <= 1.0:
        return ""
    return (f"the paper's side can close it: a ranging-limited error scales with the range error, so "
            f"{paper + explained:.3f} / {ours:.3f} = {k:.2f} times less accurate ranges than ours (median error "
            f"{k * median_m:.3f} m against our {median_m:.3f} m), i.e. an independent error of sqrt({k:.2f}^2 - 1) x "
            f"{median_m:.3f} = {math.sqrt(k * k - 1.0) * median_m:.3f} m (median) that our data lack")


def gap_account(gap: float, parts: list[tuple[str, float]], needed: str = "") -> str:
    """The gap (ours - paper, m) against the mechanisms' predicted contributions (contributions):
    their sum, linear, and the unexplained rest, gap - sum (negative: the mechanisms predict more
    than the gap, i.e. the paper's data carry part of them too). The sum is an order of magnitude,
    not a bound: the NLOS term is a range RMS taken for a position error (no geometry factor),
    a rests term can be negative, and independent errors add in quadrature. Below the paper
    (gap < 0) only terms that lower ours against the paper's count (errors the paper's data carry
    and ours lack, negative); `needed`: what the paper's side needs for the rest (ranging_needed)."""
    if gap < 0:
        parts = [(text, value) for text, value in parts if value < 0]
    if not parts and not needed:
        return f"No mechanism quantified for this cell: the gap {gap:+.3f} m is not accounted for by a computed contribution."
    total = sum(value for _, value in parts)
    head = ("Account of the gap (we are below the paper: only errors the paper's data carry and ours lack, or "
            "errors ours lack, can close it): " if gap < 0 else "Account of the gap: ")
    terms = "; ".join(text for text, _ in parts)
    account = (f"{terms}; predicted {total:+.3f} m against the gap {gap:+.3f} m: {gap - total:+.3f} m unexplained"
               if parts else
               f"no computed term {'lowers' if gap < 0 else 'raises'} ours: the gap {gap:+.3f} m is unexplained")
    return head + account + (f"; {needed}." if needed else ".")


def outside_cells(tables: list[dict]) -> list[tuple[dict, dict, str, dict]]:
    """(table, row, column, cell) of every table cell with a paper value outside our interval."""
    return [(table, row, column, cell) for table in tables for row in table["rows"]
            for column, cell in zip(table["columns"], row["cells"])
            if cell["paper"] is not None and cell["value"] is not None and not cell["inside"]]


def cell_whys(n: Numbers, experiment: str, tables: list[dict], paper_terms=None) -> list[str]:
    """One sentence per table cell whose paper value lies outside our interval: our value with
    the interval it was compared with, the paper's, the cell's measured error sources
    (cell_mechanism of the cell's scenario) and, for RMSE and max-error cells, the account of
    the gap (gap_account) from the computed contributions (contributions; for a fused cell
    without rests, drift_counterfactual in place of the ranging terms), the paper's own
    `paper_terms(table, row, column, cell)` (a list of (text, contribution in m), e.g. a model's
    part of the gap; contribution None: what the paper's side needs, a statement) and, below
    the paper on range-based cells, what the paper's ranging needs for the rest (ranging_needed)."""
    out = []
    for table, row, column, cell in outside_cells(tables):
        scenario = cell.get("scenario") or table.get("scenario", "")
        low, high = ((cell["band_low"], cell["band_high"]) if cell["basis"] == "run" else (cell["low"], cell["high"]))
        interval = (f"{cell['basis']} interval [{low:.3f}, {high:.3f}]" if low is not None and high is not None
                    else "no interval")
        labels = (table["title"], row["label"], column)
        mechanism = cell_mechanism(n, experiment, scenario, *labels)
        side = "below" if cell["value"] < cell["paper"] else "above"
        name = table["title"].split(":")[0].split(" (")[0]
        where = f"{column} ({scenario})" if scenario and scenario != column else column
        parts = contributions(n, experiment, scenario, table, row["label"], cell["value"], *labels)
        others = {c.get("scenario") or col: c["value"] for col, c in zip(table["columns"], row["cells"])
                  if col != column and c["value"] is not None}
        drift = drift_counterfactual(n, experiment, scenario, cell["value"], others, *labels)
        if drift:
            parts = drift + [p for p in parts if p[0].startswith("rests")]
        own = paper_terms(table, row, column, cell) if paper_terms else []
        parts += [(text, value) for text, value in own if value is not None]
        needed = ""
        if cell["delta"] < 0 and _words(*labels) & set(RANGING_WORDS):
            explained = sum(value for _, value in parts if value < 0)
            needed = ranging_needed(cell["value"], cell["paper"], explained, n.ranging(scenario)["los_median_m"])
        needed = "; ".join(filter(None, [needed, *(text for text, value in own if value is None)]))
        out.append(f"{name}, {row['label']} / {where}: ours {cell['value']:.3f} "
                   f"({interval}) is {side} the paper's {cell['paper']:.3f} by {abs(cell['delta']):.3f}; "
                   + (f"measured here: {mechanism}." if mechanism else
                      "no data-quality figures for this scenario in the build.")
                   + (f" {gap_account(cell['delta'], parts, needed)}" if _words(*labels) & set(GAP_WORDS) else ""))
    return out


OWN_MODEL_TEST = "tests/test_spatial.py::test_3d_flight_rmse_is_within_1_5_of_the_pcrb"   # data from the filter's model


def study_bound_whys(n: Numbers, study: dict) -> list[str]:
    """One sentence per scenario of a study section (report.sections.study_section) with a
    Bayesian cell whose RMSE / sqrt(PCRB) exceeds 1 or whose ANEES is above its band: each such
    cell's ratio and ANEES verdict, beside what the bound and the filter's Gaussian model lack in
    that scenario's data (Numbers.ranging, the data summary: the NLOS share of the run's two-way
    ranges, their median excess and 95th percentile against the LOS median error) and the share
    the gate rejected; then one sentence on where the ratio on data drawn from the filter's own
    model is measured."""
    out = []
    for table in study["tables"]:
        for k, scenario in enumerate(table["scenarios"]):
            cells = []
            for row in table["rows"]:
                cell = row["cells"][k]
                ratio, anees = cell["efficiency"]["value"], cell["anees"]
                if ratio is None or not (ratio > 1 or anees.get("verdict") == "optimistic"):
                    continue
                verdict = (f", ANEES {anees['value']:.2f} {anees['verdict']} (band [{anees['band_low']:.2f}, "
                           f"{anees['band_high']:.2f}])" if anees.get("verdict") else "")
                gated = (f", gate rejected {cell['gated']['value']:.0%}" if cell["gated"]["value"] is not None else "")
                cells.append(f"{row['label']} {ratio:.2f}{verdict}{gated}")
            r = n.ranging(scenario)
            if not cells or not finite(r["nlos_share"], r["nlos_bias_m"], r["los_median_m"]):
                continue
            differences = "tdoa" in scenario.split("/", 1)[1]
            out.append(
                f"{scenario} (subset {table.get('subset', 'all')}): RMSE / sqrt(PCRB) {'; '.join(cells)}. The bound "
                f"and the filters model zero-mean Gaussian {'range differences' if differences else 'ranges'}; in "
                f"this scenario's data (its two-way ranges, data summary) {r['nlos_share']:.0%} of the valid ranges "
                f"are NLOS, with a median excess of {r['nlos_bias_m']:.2f} m (95th percentile {r['nlos_p95_m']:.2f} m) "
                f"against a LOS median error of {r['los_median_m']:.2f} m"
                + ("; a range difference carries the excess of both its arrivals" if differences else "")
                + ". What the gate lets through enters the track as a bias the filter's covariance does not hold.")
    if out:
        out.append(f"On data drawn from the filter's own model (Gaussian ranges, no NLOS) the ratio is near 1: "
                   f"{OWN_MODEL_TEST} prints it for a 3-D flight and requires 0.67-1.5 (docs/studies.md).")
    return out
