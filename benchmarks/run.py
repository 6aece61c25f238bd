"""Performance measurements of wsnloc on this machine; writes benchmarks/RESULTS.md.

    python benchmarks/run.py [--repeats 3] [--scaling 20 100 500]

Every figure is the median of repeated runs. Workflow timings run in scratch copies of
the workflow under benchmarks/out/ (git-ignored), never in the working tree.
"""

from __future__ import annotations

import argparse
import datetime
import io
import platform
import re
import resource
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.csv as pacsv
import yaml

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "out"


def median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def workflow_copy(name: str, edit=None) -> Path:
    target = OUT / name
    if target.exists():
        shutil.rmtree(target)
    target.mkdir(parents=True)
    shutil.copy(ROOT / "Snakefile", target)
    shutil.copytree(ROOT / "workflow", target / "workflow")
    shutil.copytree(ROOT / "config", target / "config")
    if edit:
        path = target / "config" / "config.yaml"
        config = yaml.safe_load(path.read_text())
        edit(config)
        path.write_text(yaml.safe_dump(config))
    return target


def children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def snakemake(cwd: Path, *args) -> tuple[float, str]:
    start = time.perf_counter()
    result = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "2", *args], cwd=cwd,
                            capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if result.returncode != 0:
        raise RuntimeError(f"snakemake failed in {cwd}:\n{result.stderr[-2000:]}")
    return elapsed, result.stdout + result.stderr


def seconds_per_rule(log: str) -> dict[str, tuple[int, float]]:
    """(jobs, summed job wall time in s) per rule, from the timestamps Snakemake logs when a
    job starts and when it finishes (1 s resolution), largest first."""
    stamp, rule, started, total = None, None, {}, {}
    for line in log.splitlines():
        if m := re.match(r"\[(\w{3} \w{3} +\d+ [\d:]+ \d{4})\]", line):
            stamp = datetime.datetime.strptime(m.group(1), "%a %b %d %H:%M:%S %Y")
        elif m := re.match(r"(?:local)?rule (\w+):", line):
            rule = m.group(1)
        elif m := re.match(r"\s+jobid: (\d+)", line):
            started[m.group(1)] = (rule, stamp)
        elif (m := re.match(r"Finished jobid: (\d+)", line)) and m.group(1) in started:
            name, begin = started[m.group(1)]
            jobs, seconds = total.get(name, (0, 0.0))
            total[name] = (jobs + 1, seconds + (stamp - begin).total_seconds())
    return dict(sorted(total.items(), key=lambda kv: -kv[1][1]))


def jobs_run(log: str) -> list[str]:
    return re.findall(r"^(?:local)?rule (\w+):", log, flags=re.M)


def bench_workflow(repeats: int) -> dict:
    colds, cpus, noops = [], [], []
    for k in range(repeats):
        work = workflow_copy(f"cold-{k}")
        cpu_before = children_cpu_s()
        elapsed, log = snakemake(work)
        colds.append(elapsed)
        cpus.append(children_cpu_s() - cpu_before)
        jobs = jobs_run(log)
        if k == 0:
            per_rule = seconds_per_rule(log)
        noops.append(statistics.median(snakemake(work)[0] for _ in range(3)))
    config = work / "config" / "config.yaml"
    text = config.read_text()
    config.write_text(text.replace("tracker: {window: 6,", "tracker: {window: 5,"))
    edit_time, log = snakemake(work)
    return {"cold_s": statistics.median(colds), "cold_all": colds, "jobs": len(jobs),
            "cold_cpu_s": statistics.median(cpus), "per_rule": per_rule,
            "noop_s": statistics.median(noops), "edit_s": edit_time, "edit_jobs": jobs_run(log)}


def bench_filters(repeats: int) -> list[tuple[str, float, float]]:
    """Time per step (us) of our filters and filterpy's on identical inputs."""
    from filterpy.kalman import ExtendedKalmanFilter as FpEKF
    from filterpy.kalman import KalmanFilter as FpKF

    from wsnloc.filters.kalman import ExtendedKalmanFilter, KalmanFilter
    from wsnloc.filters.measurement_models import RangeModel, Stacked
    from wsnloc.filters.motion_models import constant_velocity

    rng = np.random.default_rng(0)
    n = 5000
    F, Q = constant_velocity(0.5, 0.3)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    R = np.eye(2)
    zs = rng.normal(0, 1, (n, 2))
    anchors = rng.uniform(0, 20, (8, 2))
    model = Stacked([RangeModel(anchors, np.full(8, 0.3))], np.zeros(8))
    ranges = rng.uniform(1, 15, (n, 8))

    def ours_kf():
        kf = KalmanFilter(np.zeros(4), np.eye(4), F, Q, H, R)
        for z in zs:
            kf.predict()
            kf.update(z)

    def fp_kf():
        kf = FpKF(dim_x=4, dim_z=2)
        kf.F, kf.Q, kf.H, kf.R = F, Q, H, R
        for z in zs:
            kf.predict()
            kf.update(z)

    def ours_ekf():
        ekf = ExtendedKalmanFilter(np.array([5.0, 5.0, 0, 0]), np.eye(4), F, Q)
        for z in ranges:
            ekf.predict()
            ekf.update_nonlinear(z, model.h, model.jacobian, model.R())

    def fp_ekf():
        ekf = FpEKF(dim_x=4, dim_z=8)
        ekf.x, ekf.F, ekf.Q = np.array([5.0, 5.0, 0, 0]), F, Q
        for z in ranges:
            ekf.predict()
            ekf.update(z, HJacobian=model.jacobian, Hx=model.h, R=model.R())

    rows = []
    for name, ours, ref in (("KF, PV model, 2-D position fixes (paper D)", ours_kf, fp_kf),
                            ("EKF, PV model, 8 ranges per update (papers A, C)", ours_ekf, fp_ekf)):
        a = median_time(ours, repeats) / n * 1e6
        b = median_time(ref, repeats) / n * 1e6
        rows.append((name, a, b))
    return rows


ESTIMATOR_CASES = (   # (label, registry name, parameters): the filter family of issue 17 and the EKF baselines
    ("EKF, epoch updates", "ekf", {}),
    ("EKF, sequential updates (tracker)", "tracker", {}),
    ("UKF, epoch updates", "ukf", {}),
    ("particle filter, 1000 particles, epoch updates", "pf", {"n_particles": 1000}),
    ("particle filter, 1000 particles, sequential updates", "pf", {"n_particles": 1000, "update": "sequential"}),
    ("EKF + RTS smoother, epoch updates", "ekf_rts", {}),
    ("sliding-window batch, W = 2 s", "sliding_window", {}),
)


def bench_estimators(repeats: int, scenarios=("constant", "variable")) -> list[dict]:
    """Time per output step (us) of each registry estimator on one simulated Newcom++ run per
    scenario (all 12 UWB anchors, 0.5 s epochs; a fresh RunData per repeat, so building the
    epochs and measurement models is counted), and the real-time factor: the run's duration
    covered by the estimates (steps x 0.5 s) over the compute time (> 1: faster than real time)."""
    from wsnloc.campaign import Campaign
    from wsnloc.estimate import load_run
    from wsnloc.estimators import registry
    from wsnloc.estimators.run_data import RunData
    from wsnloc.sim.newcom import simulate_run
    from wsnloc.sim.seeding import run_seed_sequence

    campaign = Campaign.load(ROOT / "config" / "campaigns" / "newcom.yaml")
    rows = []
    for scenario in scenarios:
        raw = simulate_run(campaign, scenario, run_seed_sequence(1, "bench", scenario, 1),
                           OUT / f"estimators-{scenario}")
        run_tables = load_run("newcom", raw, campaign, OUT / f"estimators-{scenario}-tables")
        for label, name, params in ESTIMATOR_CASES:
            p = dict(params, max_range_m=50.0)

            def once(name=name, p=p, scenario=scenario):
                return registry.run(name, RunData(run_tables, campaign, None, scenario), p)
            steps = len(once())
            seconds = median_time(once, repeats)
            epoch_s = registry.get(name).resolve(p)["epoch_s"]
            rows.append({"scenario": scenario, "estimator": label, "steps": steps, "us_per_step": seconds / steps * 1e6,
                         "realtime_factor": steps * epoch_s / seconds})
    return rows


def bench_ingest(repeats: int) -> dict:
    """Our imu.log parser (with per-line quarantine) against pyarrow.csv.read_csv on the same bytes."""
    from wsnloc.campaign import Campaign
    from wsnloc.io.newcom import parse_imu
    from wsnloc.io.rawlines import Quarantine, read_raw
    from wsnloc.signal.resample import resample_imu
    from wsnloc.sim.newcom import simulate_run
    from wsnloc.sim.seeding import run_seed_sequence

    campaign = Campaign.load(ROOT / "config" / "campaigns" / "newcom.yaml")
    run = simulate_run(campaign, "variable", run_seed_sequence(1, "bench", "variable", 1), OUT / "ingest-run")
    path = run / "imu.log"
    data = path.read_bytes()
    megabytes = len(data) / 1e6

    def ours():
        quarantine = Quarantine()
        return parse_imu(read_raw(path, quarantine), campaign, quarantine)

    def arrow():
        return pacsv.read_csv(io.BytesIO(data), read_options=pacsv.ReadOptions(skip_rows=3, autogenerate_column_names=True),
                              parse_options=pacsv.ParseOptions(delimiter=" "))

    t_ours, t_arrow = median_time(ours, repeats), median_time(arrow, repeats)
    imu = ours()
    t_resample = median_time(lambda: resample_imu(imu, 5.0, 500.0, 0.1, 8.0), repeats)
    return {"mb": megabytes, "ours_mbps": megabytes / t_ours, "arrow_mbps": megabytes / t_arrow,
            "samples": len(imu), "resample_sps": len(imu) / t_resample}


def bench_scaling(sizes: list[int]) -> list[tuple[int, float, int]]:
    """Wall time of a cold build of newcom/constant with paper D, for several run counts."""
    def edit_for(runs):
        def edit(config):
            config["runs"] = runs
            config["datasets"] = {"newcom": dict(config["datasets"]["newcom"], scenarios=["constant"])}
            experiments = config["experiments"]
            experiments["paper_d"]["scenarios"] = ["newcom/constant"]
            for name in ("paper_a", "paper_b", "paper_c", "generic_ekf"):
                experiments.pop(name, None)
        return edit

    out = []
    for runs in sizes:
        work = workflow_copy(f"scaling-{runs}", edit_for(runs))
        elapsed, log = snakemake(work)
        out.append((runs, elapsed, len(jobs_run(log))))
        shutil.rmtree(work / "data")
    return out


def machine() -> str:
    import os

    cpu = platform.processor() or platform.machine()
    return f"{platform.system()} {platform.machine()} ({cpu}), {os.cpu_count()} cores, Python {platform.python_version()}"


EDIT_AFFECTED = {"paper_d", "paper_d_summary", "report", "all"}   # what the tracker window feeds


def _met(ok: bool) -> str:
    return "yes" if ok else "**no**"


def write(results: dict, path: Path, command: str) -> None:
    w, f, i, s = results["workflow"], results["filters"], results["ingest"], results["scaling"]
    e = results["estimators"]
    lines = [
        "# wsnloc benchmarks", "",
        f"Machine: {machine()}  ", f"Command: `{command}`  ",
        f"Date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; every figure is a median of repeated runs.", "",
        "## Workflow (default config: 6 scenarios x 20 runs, papers A-D)", "",
        "| measure | value | target | met |", "|---|---|---|---|",
        f"| cold `snakemake --cores 2` | {w['cold_s']:.1f} s ({', '.join(f'{x:.1f}' for x in w['cold_all'])}), "
        f"{w['jobs']} jobs | <= 60 s | {_met(w['cold_s'] <= 60)} |",
        f"| no-op re-run | {w['noop_s']:.1f} s | <= 5 s | {_met(w['noop_s'] <= 5)} |",
        f"| after editing `experiments.paper_d.tracker.window` | {w['edit_s']:.1f} s; re-ran: {', '.join(w['edit_jobs'])} "
        f"| only the affected jobs | {_met(set(w['edit_jobs']) <= EDIT_AFFECTED)} |",
        "", f"CPU time of a cold build (snakemake and its jobs, user + system): {w['cold_cpu_s']:.0f} s "
        f"on 2 cores, so at least {w['cold_cpu_s'] / 2:.0f} s of wall time.", "",
        "Where it goes (first cold build; job wall time summed per rule, from Snakemake's log, 1 s resolution):", "",
        "| rule | jobs | job time [s] |", "|---|---|---|",
        *[f"| {rule} | {jobs} | {seconds:.0f} |" for rule, (jobs, seconds) in w["per_rule"].items()],
        "", "## Estimator time per step against filterpy (same inputs, same run)", "",
        "| filter | wsnloc [us/step] | filterpy [us/step] | ratio (ours / filterpy) |", "|---|---|---|---|",
        *[f"| {name} | {a:.1f} | {b:.1f} | {a / b:.2f} |" for name, a, b in f],
        "", f"Target: no slower than filterpy (ratio <= 1): {_met(all(a <= b for _, a, b in f))}.",
        "", "## Estimators: time per step on a simulated Newcom++ run (registry, 12 UWB anchors, 0.5 s epochs)", "",
        "| scenario | estimator | output steps | time per step [us] | real-time factor |", "|---|---|---|---|---|",
        *[f"| {r['scenario']} | {r['estimator']} | {r['steps']} | {r['us_per_step']:.0f} | {r['realtime_factor']:.0f} |"
          for r in e],
        "", "Real-time factor: the run time covered by the estimates over the compute time. Target: the particle "
        "filter at 1000 particles faster than real time on the Newcom++ scenarios: "
        f"{_met(all(r['realtime_factor'] > 1 for r in e if r['estimator'].startswith('particle')))}.",
        "", "## Ingest and resampling", "",
        "| measure | value |", "|---|---|",
        f"| imu.log parse ({i['mb']:.1f} MB, per-line validation + quarantine) | {i['ours_mbps']:.1f} MB/s |",
        f"| pyarrow.csv.read_csv on the same bytes (no validation) | {i['arrow_mbps']:.1f} MB/s (ratio {i['ours_mbps'] / i['arrow_mbps']:.3f}) |",
        f"| IMU resampling 500 Hz -> 5 Hz | {i['resample_sps'] / 1e6:.2f} M samples/s ({i['samples']} samples) |",
        "", "## Monte Carlo scaling (newcom/constant with paper D, cold build)", "",
        "| runs per scenario | wall time [s] | jobs | s per run |", "|---|---|---|---|",
        *[f"| {n} | {t:.1f} | {j} | {t / n:.2f} |" for n, t, j in s], "",
    ]
    if len(s) >= 2:
        slope = np.polyfit([n for n, _, _ in s], [t for _, t, _ in s], 1)
        lines.append(f"Linear fit: {slope[0]:.3f} s per run + {slope[1]:.1f} s fixed (job start-up).")
    path.write_text("\n".join(lines) + "\n")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scaling", type=int, nargs="*", default=[20, 100, 500])
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    results = {"filters": bench_filters(args.repeats), "estimators": bench_estimators(args.repeats),
               "ingest": bench_ingest(args.repeats),
               "workflow": bench_workflow(args.repeats), "scaling": bench_scaling(args.scaling)}
    command = "python benchmarks/run.py " + " ".join(sys.argv[1:])
    write(results, ROOT / "benchmarks" / "RESULTS.md", command.strip())
    print((ROOT / "benchmarks" / "RESULTS.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
