"""Every registry estimator on asynchronous data: the shared real runs and a synthetic run
ranged one anchor at a time, each through `wsnloc estimate` (estimate.estimate_run) with the
estimator's defaults.

    python benchmarks/async_estimators.py [--realdata ../shared/realdata] [--out benchmarks/out/async]
                                          [--estimators ekf,pf] [--cases los/trajectory-a-case-1]

Runs: cucudasluv (outdoor UWB, 4 anchors ranged ~1 ms apart, 6 cases, `wsnloc convert`),
philotuxo (BLE RSSI, 5 tracks, the estimators that read RSS, with `--calibration` = the next
track, as benchmarks/realdata.py) and `synthetic/one_at_a_time`: a 1 m/s walk around a 10 m
square inside 4 anchors (20 m square), ranges (0.1 m noise) to one random anchor at a time,
Poisson arrivals at 4 Hz, 600 s (seeded). Estimators needing an IMU are skipped (these runs
have none); those reading only ranges are skipped on the RSS-only tracks.
Per (run, estimator): exit (ok or the error), availability, median and RMSE of the 2-D error
(m), median / tracker's median on the same run, resets and the numerical-guard counters
(`regularised`, `skipped`, `reinitialised` where the estimator has them). Prints the command,
the median / tracker's per run and estimator and that full table in Markdown, then what the data
allow: per run the share of the truth span between its first and last measurement (the ceiling
of availability) and, on the synthetic run, the best median of a random-walk EKF written here
apart from the package (the ceiling of a position-only model such as `ekf_p`) and the medians
of the trackers over fixes on its noise-free twin (the ceiling set by their fixes); writes them
to OUT/async_estimators.md (the table also as .csv; the scratch folder is git-ignored); with
--docs, also between the markers of benchmarks/ASYNC_RESULTS.md (publish.py).
"""

from __future__ import annotations

import argparse
import sys
import time
import traceback
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from publish import publish  # noqa: E402
from wsnloc.estimate import estimate_run  # noqa: E402
from wsnloc.estimators import registry  # noqa: E402
from wsnloc.io.convert import convert_cucudasluv, convert_philotuxo  # noqa: E402
from wsnloc.io.generic import ingest_run, run_campaign  # noqa: E402
from wsnloc.metrics.tracking import run_metrics, score, truth_span  # noqa: E402
from wsnloc.studies import reads_rss  # noqa: E402

INERTIAL_TABLES = {"imu", "imu_5hz"}
COUNTERS = ("resets", "regularised", "skipped", "reinitialised")
ANCHORS = {"A1": (0.0, 0.0), "A2": (20.0, 0.0), "A3": (20.0, 20.0), "A4": (0.0, 20.0)}


def synthetic_run(folder: Path, seed: int = 7, duration_s: float = 600.0, rate_hz: float = 4.0,
                  speed_mps: float = 1.0, noise_m: float = 0.1) -> Path:
    """A generic run: ranges to one random anchor at a time (see the module docstring)."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.exponential(1.0 / rate_hz, int(duration_s * rate_hz * 1.5)))
    t = t[t < duration_s]
    ids = rng.choice(np.array(list(ANCHORS)), len(t))

    def walk(times):
        s = np.mod(speed_mps * times, 40.0)
        corners = np.array([[5.0, 5.0], [15.0, 5.0], [15.0, 15.0], [5.0, 15.0], [5.0, 5.0]])
        side = np.floor_divide(s, 10.0).astype(int)
        return corners[side] + (corners[side + 1] - corners[side]) * (np.mod(s, 10.0) / 10.0)[:, None]

    xy = np.array([ANCHORS[a] for a in ids])
    ranges = np.hypot(*(walk(t) - xy).T) + rng.normal(0.0, noise_m, len(t))
    folder.mkdir(parents=True, exist_ok=True)
    pd.DataFrame({"anchor_id": list(ANCHORS), "tech": "uwb", "x": [v[0] for v in ANCHORS.values()],
                  "y": [v[1] for v in ANCHORS.values()]}).to_csv(folder / "anchors.csv", index=False)
    pd.DataFrame({"t": t, "anchor_id": ids, "range_m": ranges}).to_csv(folder / "ranges.csv", index=False)
    t_truth = np.arange(0.0, duration_s, 0.05)
    p = walk(t_truth)
    pd.DataFrame({"t": t_truth, "x": p[:, 0], "y": p[:, 1]}).to_csv(folder / "truth.csv", index=False)
    return folder


def measurement_span_share(run_dir: Path) -> float:
    """Share of the truth span [T0, T1] between the run's first and last usable measurement
    (ranges or RSS): an estimator outputs from its first measurement to its last, so this bounds
    its availability (metrics.tracking.availability)."""
    tables, _ = ingest_run(run_dir)
    times = np.concatenate([tables[name]["t"].to_numpy(float) for name in ("ranges", "rss") if len(tables[name])])
    t0, t1 = truth_span(tables["truth"])
    return float((min(times.max(), t1) - max(times.min(), t0)) / (t1 - t0))


def random_walk_bound(run_dir: Path, times: np.ndarray, q_grid=np.geomspace(0.01, 100.0, 25)) -> tuple[float, float]:
    """(best median 2-D error (m), its q (m^2/s)) of a minimal random-walk EKF written here apart
    from the package, on a 2-D run with truth: state x (2,), predict P += q dt I, one update per
    range r = |x - a| + n, n ~ N(0, sigma^2) with the true sigma (0.1 m), started at the true
    position, read at `times` (tracker's output times) by the last update; q over `q_grid`. The
    best any position-only (P) model can do with that information: what `ekf_p` is measured against."""
    tables, _ = ingest_run(run_dir)                       # the package's reader; the filter below is not its
    ranges, truth = tables["ranges"], tables["truth"]
    anchors = tables["anchors"].set_index("anchor_id")[["x", "y"]]
    t, r, a = ranges["t"].to_numpy(), ranges["range_m"].to_numpy(), anchors.loc[ranges["anchor_id"]].to_numpy()
    best = (np.inf, np.nan)
    for q in q_grid:
        x = np.array([np.interp(t[0], truth["t"], truth["x"]), np.interp(t[0], truth["t"], truth["y"])])
        P, states = np.eye(2) * 0.01, np.empty((len(t), 2))
        for k in range(len(t)):
            P = P + q * (t[k] - t[max(k - 1, 0)]) * np.eye(2)
            d = x - a[k]
            H = d / max(np.hypot(*d), 1e-6)
            S = H @ P @ H + 0.1 ** 2
            K = P @ H / S
            x, P = x + K * (r[k] - np.hypot(*d)), P - np.outer(K, H @ P)
            states[k] = x
        last = np.searchsorted(t, times, side="right") - 1
        keep = last >= 0
        track = pd.DataFrame({"t": times[keep], "x": states[last[keep], 0], "y": states[last[keep], 1]})
        median = run_metrics(score(track, truth), truth)["median"]
        if median < best[0]:
            best = (float(median), float(q))
    return best


def noise_free_fixes(out: Path) -> dict[str, float]:
    """Median 2-D error (m) of the trackers over fixes (paper D) and of the multilateration
    window fixes they can be fed, on the synthetic run's noise-free twin (synthetic_run with
    noise_m 0: the same times and anchors, exact ranges): what is left is the fixes' own error,
    each solved from a window of ranges taken one anchor at a time along the walk, the ceiling
    of any estimator that filters per-epoch fixes instead of the ranges."""
    run_dir = synthetic_run(out / "converted" / "synthetic" / "noise_free", noise_m=0.0)
    return {name: estimate_run("generic", run_dir, run_campaign(run_dir), out / "estimates" / "noise_free" / name,
                               name, {})["median_m"]
            for name in ("multilateration", "velocity_tracker", "kf_tracker")}


def runs(src: Path, out: Path) -> list[tuple[str, Path, Path | None, bool]]:
    """(label, run folder, calibration donor or None, has ranges) of every run."""
    items = []
    if (src / "cucudasluv-uwb").is_dir():
        for run in convert_cucudasluv(src / "cucudasluv-uwb", out / "converted" / "cucudasluv"):
            items.append((f"cucudasluv/{run.run_dir.parent.name}/{run.run_dir.name}", run.run_dir, None, True))
    if (src / "philotuxo-ble-rssi").is_dir():
        tracks = [r.run_dir for r in convert_philotuxo(src / "philotuxo-ble-rssi", out / "converted" / "philotuxo")]
        for i, track in enumerate(tracks):
            items.append((f"philotuxo/{track.name}", track, tracks[(i + 1) % len(tracks)], False))
    items.append(("synthetic/one_at_a_time", synthetic_run(out / "converted" / "synthetic" / "one_at_a_time"),
                  None, True))
    return items


def applicable(name: str, has_ranges: bool) -> bool:
    """Whether the estimator can run here: no IMU on these runs; RSS-only runs need an estimator
    that can read RSS (measurements_for switches measurements/fixes to rss)."""
    estimator = registry.get(name)
    p = estimator.resolve({})
    if INERTIAL_TABLES & set(estimator.tables(p)):
        return False
    if has_ranges:
        return True
    return any("rss" in (q.choices or ()) for q in estimator.params if q.name in ("measurements", "fixes")) \
        or reads_rss(name, p)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--realdata", default=str(ROOT.parent / "shared" / "realdata"),
                        help="the shared real datasets (default ../shared/realdata beside the checkout)")
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "async"))
    parser.add_argument("--estimators", default="", help="comma-separated subset (default: all)")
    parser.add_argument("--cases", default="", help="comma-separated substrings of the run labels")
    parser.add_argument("--docs", action="store_true", help="write the tables into benchmarks/ASYNC_RESULTS.md")
    args = parser.parse_args(argv)
    out, started_all = Path(args.out), time.perf_counter()
    names = [n for n in (args.estimators.split(",") if args.estimators else registry.ESTIMATORS) if n]
    if "tracker" not in names:
        names.insert(0, "tracker")
    rows, run_dirs = [], {}
    for label, run_dir, donor, has_ranges in runs(Path(args.realdata), out):
        if args.cases and not any(c in label for c in args.cases.split(",")):
            continue
        run_dirs[label] = run_dir
        for name in names:
            if not applicable(name, has_ranges):
                continue
            started = time.perf_counter()
            row = {"run": label, "estimator": name}
            try:
                metrics = estimate_run("generic", run_dir, run_campaign(run_dir), out / "estimates" / label / name,
                                       name, {}, donor)
                summary = pd.read_json(out / "estimates" / label / name / "metrics.json", typ="series")
                row.update(exit="ok", availability=metrics.get("availability", np.nan),
                           median_m=metrics.get("median_m", np.nan), rmse_m=metrics.get("rmse_m", np.nan),
                           **{c: summary.get(c, summary.get(f"diag_{c}", np.nan)) for c in COUNTERS})
            except Exception as error:          # noqa: BLE001 - the table reports every failure
                row.update(exit=f"{type(error).__name__}: {str(error).splitlines()[0][:80]}")
                traceback.print_exc(file=sys.stderr)
            row["seconds"] = time.perf_counter() - started
            rows.append(row)
            print(row, flush=True)
    table = pd.DataFrame(rows)
    tracker = table[table["estimator"] == "tracker"].set_index("run")["median_m"]
    table["vs_tracker"] = table["median_m"] / table["run"].map(tracker)
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / "async_estimators.csv", index=False)
    columns = ["run", "estimator", "exit", "availability", "median_m", "vs_tracker", "rmse_m", *COUNTERS, "seconds"]
    ratios = table.pivot(index="run", columns="estimator", values="vs_tracker")
    ratios = ratios[[n for n in names if n in ratios and n != "tracker"]]
    limits = []
    for label, run_dir in run_dirs.items():
        row = {"run": label, "measurements span / truth span": measurement_span_share(run_dir)}
        tracker_out = out / "estimates" / label / "tracker" / "estimates.parquet"
        if label.startswith("synthetic") and tracker_out.is_file() and label in tracker.index:
            median, q = random_walk_bound(run_dir, pd.read_parquet(tracker_out)["t"].to_numpy(float))
            row.update({"random-walk EKF, best q: median_m": median, "its q_m2ps": q,
                        "its median / tracker's": median / tracker[label]})
            row.update({f"noise-free ranges: {name} / tracker's": median / tracker[label]
                        for name, median in noise_free_fixes(out).items()})
        limits.append(row)
    command = " ".join(["python benchmarks/async_estimators.py", *(sys.argv[1:] if argv is None else argv)])
    publish([f"`{command}` ({time.strftime('%Y-%m-%d', time.gmtime())}, "
             f"{time.perf_counter() - started_all:.0f} s)", "",
             "Median 2-D error / `tracker`'s on the same run:", "", ratios.to_markdown(floatfmt=".2f"), "",
             "Every (run, estimator):", "", table.reindex(columns=columns).to_markdown(index=False, floatfmt=".3g"),
             "", "What the data allow: the share of the truth span between the first and the last "
             "measurement (`measurement_span_share`: no estimator that needs measurements covers more), "
             "and on the synthetic run what a position-only model can reach (`random_walk_bound`: an EKF "
             "written apart from the package, true sigma, true start, best q of a grid; `ekf_p` is "
             "measured against it) and what per-epoch fixes can reach (`noise_free_fixes`: the trackers over "
             "fixes and multilateration on the run's noise-free twin, median / tracker's median on the "
             "noisy run):", "", pd.DataFrame(limits).to_markdown(index=False, floatfmt=".3g")],
            out, "async_estimators", "benchmarks/ASYNC_RESULTS.md" if args.docs else None)
    return 0


if __name__ == "__main__":
    sys.exit(main())
