"""Performance measurements of wsnloc on this machine, as ratios measured in one run; writes
benchmarks/RESULTS.md.

    python benchmarks/run.py --previous REV [--repeats 3] [--mc-runs 5 10 20] [--mc-repeats 2] [--small] [--cold-only]

REV is the commit to compare against (e.g. the last commit before a performance change). It is
exported with `git archive` into benchmarks/out/previous/ (no worktree, no checkout) and its
workflow runs there with its own PYTHONPATH, beside the current code, in the same run.
Absolute times differ 2x and more between machines, so the acceptance figures are ratios:
- import floor: minimum over 5 runs of `python -c "import numpy, pandas, ..."` (IMPORT_FLOOR),
  measured right before each cold build (the speed of a shared machine drifts over minutes);
- cold build (wall, and CPU = user + system of snakemake and every job it started) / the floor
  measured before it, the median over the builds; the builds of both revisions alternate, so
  the CPU ratio current / previous is measured under the same load;
- Monte Carlo cost per added run: slope of a least-squares line through cold-build times at
  several run counts, current / previous; the builds of both revisions alternate, each point
  is the fastest of `--mc-repeats` builds (a build slowed by a busy neighbour is not kept);
- estimators per step against filterpy on identical inputs.
`--small` uses one scenario per dataset (a test of this script, not a benchmark); `--cold-only`
measures the alternating cold builds only (a reduced run on a busy machine). All builds
run in scratch copies under benchmarks/out/ (git-ignored), never in the working tree.
"""

from __future__ import annotations

import argparse
import ast
import datetime
import os
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
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))          # this tree's wsnloc (filters, estimators)

OUT = ROOT / "benchmarks" / "out"
IMPORT_FLOOR = "import numpy, pandas, pyarrow.parquet, scipy.signal, matplotlib.pyplot"
SIM_SCENARIO = ("newcom", "variable")
SIM_RUNS = 5


def script_imports(scripts) -> list[str]:
    """The module-level import statements of workflow scripts, each once, in order of first
    appearance (e.g. "from wsnloc.report import figures"): what a `script:` job runs first."""
    statements: dict[str, None] = {}
    for script in scripts:
        body = ast.parse(Path(script).read_text()).body
        statements.update(dict.fromkeys(ast.unparse(node) for node in body
                                        if isinstance(node, (ast.Import, ast.ImportFrom))))
    return list(statements)


def median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def children_cpu_s() -> float:
    """User + system CPU seconds of every finished descendant (jobs count through snakemake)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def become_subreaper() -> None:
    """Make this process the reaper of its orphaned descendants (Linux PR_SET_CHILD_SUBREAPER):
    a process that snakemake started but did not wait for (e.g. a server of its jobs) is then
    waited for here, by reap_orphans, and its CPU counts in children_cpu_s like any job's."""
    import ctypes

    PR_SET_CHILD_SUBREAPER = 36
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)


def reap_orphans(timeout_s: float = 30.0) -> None:
    """Wait for the descendants left behind by a finished build (see become_subreaper)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            time.sleep(0.05)


def python(code: str, src: Path) -> tuple[float, str]:
    """Wall seconds and stdout of `python -c code` with `src` on PYTHONPATH."""
    start = time.perf_counter()
    result = subprocess.run([sys.executable, "-c", code], env={**os.environ, "PYTHONPATH": str(src)},
                            capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if result.returncode != 0:
        raise RuntimeError(f"python -c {code!r} failed:\n{result.stderr[-2000:]}")
    return elapsed, result.stdout


def import_floor() -> float:
    return min(python(IMPORT_FLOOR, ROOT / "src")[0] for _ in range(5))


def export_revision(rev: str) -> Path:
    """The tree of commit `rev` in benchmarks/out/previous (git archive: no checkout, no worktree)."""
    target = OUT / "previous"
    if target.exists():
        shutil.rmtree(target)
    target.mkdir(parents=True)
    archive = subprocess.run(["git", "archive", "--format=tar", rev], cwd=ROOT, capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(target)], input=archive.stdout, check=True)
    return target


def small_config(config: dict) -> None:
    """One scenario per dataset (the shape of tests/conftest.py::small_workflow)."""
    config["datasets"]["newcom"]["scenarios"] = ["constant"]
    config["datasets"]["cricket"]["scenarios"] = ["speed_40"]
    experiments = config["experiments"]
    for name in ("paper_a", "paper_b", "paper_d"):
        experiments[name]["scenarios"] = ["newcom/constant"]
    experiments["paper_b"]["simulation_scenarios"] = []
    experiments["paper_b"]["overrides"] = {}      # its simulation scenario's
    experiments["paper_d"]["cost_iterations"] = 500
    experiments["paper_c"]["scenarios"] = ["cricket/speed_40"]
    experiments["paper_c"]["table_2_scenario"] = "cricket/speed_40"
    for study in config.get("studies", {}).values():
        study["scenarios"] = ["newcom/constant", "cricket/speed_40"]


def workflow_copy(tree: Path, name: str, runs: int | None, small: bool) -> Path:
    """A scratch copy of `tree`'s workflow and config, with `runs` and --small applied."""
    target = OUT / name
    if target.exists():
        shutil.rmtree(target)
    target.mkdir(parents=True)
    shutil.copy(tree / "Snakefile", target)
    for folder in ("workflow", "config", "profiles"):     # profiles/default: Snakemake's workflow profile
        if (tree / folder).is_dir():
            shutil.copytree(tree / folder, target / folder)
    path = target / "config" / "config.yaml"
    config = yaml.safe_load(path.read_text())
    if runs is not None:
        config["runs"] = runs
    if small:
        small_config(config)
    path.write_text(yaml.safe_dump(config))
    return target


def snakemake(cwd: Path, src: Path) -> dict:
    """One `snakemake --cores 2` in `cwd` with `src` on PYTHONPATH: wall, CPU and log (the
    rules' job blocks printed whatever a tree's workflow profile says: they are parsed)."""
    cpu_before = children_cpu_s()
    start = time.perf_counter()
    result = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "2", "--quiet", "host"], cwd=cwd,
                            env={**os.environ, "PYTHONPATH": str(src)}, capture_output=True, text=True)
    wall = time.perf_counter() - start
    reap_orphans()
    if result.returncode != 0:
        raise RuntimeError(f"snakemake failed in {cwd}:\n{result.stderr[-3000:]}")
    log = result.stdout + result.stderr
    return {"wall": wall, "cpu": children_cpu_s() - cpu_before, "log": log, "jobs": jobs_run(log)}


def jobs_run(log: str) -> list[str]:
    return re.findall(r"^(?:local)?rule (\w+):", log, flags=re.M)


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


def last_job_alone_s(log: str) -> float:
    """Seconds at the end of the build during which at most one job ran (one core idle)."""
    stamp, events = None, []
    for line in log.splitlines():
        if m := re.match(r"\[(\w{3} \w{3} +\d+ [\d:]+ \d{4})\]", line):
            stamp = datetime.datetime.strptime(m.group(1), "%a %b %d %H:%M:%S %Y")
        elif re.match(r"\s+jobid: \d+", line):
            events.append((stamp, +1))
        elif re.match(r"Finished jobid: \d+", line):
            events.append((stamp, -1))
    running, alone_since = 0, None
    for when, delta in events:
        running += delta
        alone_since = (alone_since or when) if running <= 1 else None
    return (events[-1][0] - alone_since).total_seconds() if events and alone_since else 0.0


def bench_workflow(trees: dict[str, Path], repeats: int, small: bool) -> dict:
    """Cold builds of each tree's workflow, alternating tree by tree, each after an import floor
    of its own; per tree the build with the median wall / floor ratio, and the median CPU."""
    builds = {label: [] for label in trees}
    noops = []
    for k in range(repeats):
        for label, tree in trees.items():
            floor = import_floor()
            work = workflow_copy(tree, f"cold-{label}-{k}", None, small)
            builds[label].append({**snakemake(work, tree / "src"), "floor": floor})
            if label == "current":
                noops.append(min(snakemake(work, tree / "src")["wall"] for _ in range(3)))
    out = {}
    for label, runs in builds.items():
        median = sorted(runs, key=lambda b: b["wall"] / b["floor"])[len(runs) // 2]
        out[label] = {"cold_s": median["wall"], "floor_s": median["floor"],
                      "cpu_s": statistics.median(b["cpu"] for b in runs),
                      "cold_all": [(b["wall"], b["floor"], b["cpu"]) for b in runs],
                      "jobs": len(median["jobs"]), "per_rule": seconds_per_rule(median["log"]),
                      "alone_s": last_job_alone_s(median["log"])}
    out["current"]["noop_s"] = statistics.median(noops)
    return out


def bench_job_imports(trees: dict[str, Path]) -> dict[str, dict[str, float]]:
    """Per workflow script and tree: minimum over 3 runs of a fresh interpreter doing only the
    script's imports (s), the start-up of a job in an interpreter of its own (a Snakemake
    `script:` job, or a job off Linux); the trees alternate, so that a change of load hits both
    alike."""
    out = {label: {} for label in trees}
    for script in sorted((ROOT / "workflow" / "scripts").glob("*.py")):
        for _ in range(3):
            for label, tree in trees.items():
                path = tree / "workflow" / "scripts" / script.name
                if path.exists():
                    t = python("; ".join(script_imports([path])), tree / "src")[0]
                    out[label][script.stem] = min(t, out[label].get(script.stem, t))
    return out


def seconds_per_simulated_run(tree: Path) -> float:
    """Mean seconds per simulated run of `tree`'s simulator (SIM_SCENARIO, SIM_RUNS runs, in-process)."""
    dataset, scenario = SIM_SCENARIO
    target = OUT / f"sim-{tree.name}"
    code = (
        "import time; from pathlib import Path\n"
        "from wsnloc.campaign import Campaign\nfrom wsnloc.sim import SIMULATORS\n"
        "from wsnloc.sim.seeding import run_seed_sequence\n"
        f"c = Campaign.load({str(tree / 'config' / 'campaigns' / (dataset + '.yaml'))!r})\n"
        "t = time.perf_counter()\n"
        f"for r in range({SIM_RUNS}):\n"
        f"    SIMULATORS[c.format](c, {scenario!r}, run_seed_sequence(1, {dataset!r}, {scenario!r}, r),"
        f" Path({str(target)!r}) / str(r))\n"
        f"print((time.perf_counter() - t) / {SIM_RUNS})\n")
    return float(python(code, tree / "src")[1])


def bench_simulator(trees: dict[str, Path]) -> dict[str, float]:
    """Seconds per simulated run per tree: best of 3 alternating measurements."""
    times = {label: [] for label in trees}
    for _ in range(3):
        for label, tree in trees.items():
            times[label].append(seconds_per_simulated_run(tree))
    return {label: min(t) for label, t in times.items()}


def bench_scaling(trees: dict[str, Path], sizes: list[int], repeats: int, small: bool
                  ) -> dict[str, list[tuple[int, float, float]]]:
    """{label: [(runs, wall s, CPU s)]}: cold builds of each tree's workflow at several run
    counts, the trees alternating build by build, each point the fastest of `repeats` builds."""
    best: dict[tuple[str, int], tuple[int, float, float]] = {}
    for _ in range(repeats):
        for runs in sizes:
            for label, tree in trees.items():
                work = workflow_copy(tree, f"scaling-{label}-{runs}", runs, small)
                build = snakemake(work, tree / "src")
                shutil.rmtree(work)
                if (label, runs) not in best or build["wall"] < best[label, runs][1]:
                    best[label, runs] = (runs, build["wall"], build["cpu"])
    return {label: [best[label, runs] for runs in sizes] for label in trees}


def slope(points: list[tuple[int, float, float]], column: int) -> float:
    return float(np.polyfit([p[0] for p in points], [p[column] for p in points], 1)[0])


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
        rows.append((name, median_time(ours, repeats) / n * 1e6, median_time(ref, repeats) / n * 1e6, "<= 1"))
    batch = batched_ekf(anchors, ranges.reshape(BATCH_RUNS, n // BATCH_RUNS, 8), F, Q)
    rows.append((f"array EKF (filter bank), {BATCH_RUNS} runs stepped together, per run-step (same {n} updates)",
                 median_time(batch, repeats) / n * 1e6, median_time(fp_ekf, repeats) / n * 1e6, "<= 0.2"))
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
        run_tables, _ = load_run("newcom", raw, campaign, OUT / f"estimators-{scenario}-tables")
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


BATCH_RUNS = 50


def batched_ekf(anchors: np.ndarray, ranges: np.ndarray, F: np.ndarray, Q: np.ndarray):
    """A function stepping the array EKF (estimators.array_ekf: the filter bank of core.epoch_loop
    for the bare EKF) over ranges (runs, steps, m) to `anchors` (range sigma 0.3 m, start
    [5, 5, 0, 0], P0 = I, as the filterpy EKF above); it checks once that run 0 ends where
    filterpy ends on the same ranges."""
    from filterpy.kalman import ExtendedKalmanFilter as FpEKF

    from wsnloc.estimators.array_ekf import Measurements, update
    from wsnloc.filters.kalman import predict
    from wsnloc.filters.measurement_models import RangeModel

    runs, steps, m = ranges.shape
    meas = Measurements.empty(runs, steps, m)
    meas.count[:], meas.anchors[:], meas.variance[:], meas.z[:] = m, anchors, 0.3**2, ranges
    every = np.arange(runs)
    epochs = [meas.at(k, every) for k in range(steps)]

    def step_all():
        x, P = np.tile([5.0, 5.0, 0.0, 0.0], (runs, 1)), np.tile(np.eye(4), (runs, 1, 1))
        for epoch in epochs:
            x, P = predict(x, P, F, Q)
            x, P, _, _ = update(x, P, epoch)
        return x

    model = RangeModel(anchors, np.full(m, 0.3))
    reference = FpEKF(dim_x=4, dim_z=m)
    reference.x, reference.F, reference.Q = np.array([5.0, 5.0, 0, 0]), F, Q
    for z in ranges[0]:
        reference.predict()
        reference.update(z, HJacobian=model.jacobian, Hx=model.h, R=model.R())
    assert np.allclose(step_all()[0], reference.x, atol=1e-6), "batched EKF and filterpy disagree"
    return step_all


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    return (f"{platform.system()} {platform.machine()} ({cpu}), {os.cpu_count()} cores, "
            f"Python {platform.python_version()}")


def _met(ok: bool) -> str:
    return "yes" if ok else "**no**"


def cold_build_lines(w: dict) -> list[str]:
    cur, prev = w["current"], w["previous"]
    floor = cur["floor_s"]
    cpu_ratio, wall_ratio = cur["cpu_s"] / prev["cpu_s"], cur["cold_s"] / prev["cold_s"]
    builds = {label: ", ".join(f"{c:.1f} / {f:.2f} / {u:.1f}" for c, f, u in w[label]["cold_all"])
              for label in ("current", "previous")}
    return [
        "## Cold build against the import floor and the previous commit", "",
        f"Import floor: the minimum of 5 runs of `python -c \"{IMPORT_FLOOR}\"`, measured right before each "
        f"cold build; the builds of the two revisions alternate. Wall ratios are those of the median build "
        f"(floor {floor:.2f} s), CPU the median over the builds.", "",
        "| measure | current | previous | current / previous | ratio to the import floor | target | met |",
        "|---|---|---|---|---|---|---|",
        f"| cold `snakemake --cores 2`, wall ({cur['jobs']} jobs now, {prev['jobs']} before) | {cur['cold_s']:.1f} s "
        f"| {prev['cold_s']:.1f} s | {wall_ratio:.2f} | {cur['cold_s'] / floor:.1f} | <= 22 x floor "
        f"| {_met(cur['cold_s'] / floor <= 22)} |",
        f"| cold build CPU (user + system, snakemake and its jobs) | {cur['cpu_s']:.1f} s | {prev['cpu_s']:.1f} s "
        f"| {cpu_ratio:.2f} | {cur['cpu_s'] / floor:.1f} | <= 1.15 x previous | {_met(cpu_ratio <= 1.15)} |",
        f"| no-op re-run (best of 3) | {cur['noop_s']:.1f} s | | | {cur['noop_s'] / floor:.1f} | | |", "",
        f"Builds (wall s / floor s / CPU s): current {builds['current']}; previous {builds['previous']}.", "",
        f"CPU seconds per job: {cur['cpu_s'] / max(cur['jobs'], 1):.2f}; average busy cores (CPU / wall): "
        f"{cur['cpu_s'] / cur['cold_s']:.2f} of 2; time at the end with at most one job running: "
        f"{cur['alone_s']:.0f} s.", "",
        "Job wall time per rule (median cold build of the current code, from Snakemake's log, 1 s resolution):", "",
        "| rule | jobs | job time [s] |", "|---|---|---|",
        *[f"| {rule} | {jobs} | {seconds:.0f} |" for rule, (jobs, seconds) in cur["per_rule"].items()],
    ]


def write(r: dict, path: Path, command: str) -> None:
    lines = [
        "# wsnloc benchmarks", "",
        f"Machine: {machine()}  ", f"Command: `{command}`  ",
        f"Date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Every ratio below comes from this one run; "
        f"\"previous\" is commit `{r['previous']}`, exported beside the current code and built in the same run.", "",
        *(["**`--small`: one scenario per dataset, a test of this script, not the acceptance measurement "
            "(run it without `--small`).**", ""] if r["small"] else []),
        *(["**`--cold-only`: the alternating cold builds only (a reduced run).**", ""] if r["cold_only"] else []),
        *cold_build_lines(r["workflow"]),
    ]
    if "imports" in r:
        imports_now, imports_before = r["imports"]["current"], r["imports"]["previous"]
        lines += [
            "", "## Start-up of a job", "",
            "Each job is a Snakemake `script:` job: a fresh interpreter that first runs its script's module-level "
            "imports (minimum of 3 runs of those imports alone, the trees alternating):", "",
            "| script | current [s] | previous [s] |", "|---|---|---|",
            *[f"| {name} | {t:.2f} | {imports_before.get(name, float('nan')):.2f} |" for name, t in imports_now.items()],
            f"| sum | {sum(imports_now.values()):.2f} | {sum(imports_before.values()):.2f} |",
        ]
    if "sim" in r:
        sim_now, sim_before = r["sim"]["current"], r["sim"]["previous"]
        lines += [
            "", "## Simulator", "",
            f"Seconds per simulated run ({'/'.join(SIM_SCENARIO)}, mean of {SIM_RUNS} runs): current {sim_now:.3f}, "
            f"previous {sim_before:.3f}, ratio {sim_now / sim_before:.2f} "
            f"(target <= 0.5: {_met(sim_now / sim_before <= 0.5)}).",
        ]
    if "scaling" in r:
        cur, prev = r["scaling"]["current"], r["scaling"]["previous"]
        slopes = {k: (slope(cur, c), slope(prev, c)) for k, c in (("wall", 1), ("cpu", 2))}
        lines += [
            "", "## Monte Carlo cost per added run (cold builds at several run counts)", "",
            f"Builds of the two revisions alternate; each point is the fastest of {r['mc_repeats']} builds.", "",
            "| runs | current wall [s] | current CPU [s] | previous wall [s] | previous CPU [s] |",
            "|---|---|---|---|---|",
            *[f"| {a[0]} | {a[1]:.1f} | {a[2]:.1f} | {b[1]:.1f} | {b[2]:.1f} |" for a, b in zip(cur, prev)], "",
            f"Fitted slope, wall: {slopes['wall'][0]:.2f} s per run now, {slopes['wall'][1]:.2f} s before, ratio "
            f"{slopes['wall'][0] / slopes['wall'][1]:.2f} "
            f"(target <= 0.5: {_met(0 < slopes['wall'][0] <= 0.5 * slopes['wall'][1])}); "
            f"CPU: {slopes['cpu'][0]:.2f} s per run now, {slopes['cpu'][1]:.2f} s before, ratio "
            f"{slopes['cpu'][0] / slopes['cpu'][1]:.2f}.",
        ]
    if "filters" in r:
        lines += [
            "", "## Estimators per step against filterpy (same inputs, same run)", "",
            "| filter | wsnloc [us/step] | filterpy [us/step] | ratio (ours / filterpy) | target |",
            "|---|---|---|---|---|",
            *[f"| {name} | {a:.2f} | {b:.1f} | {a / b:.3f} | {target} |" for name, a, b, target in r["filters"]], "",
            "", "## Estimators: time per step on a simulated Newcom++ run (registry, 12 UWB anchors, 0.5 s epochs)", "",
            "| scenario | estimator | output steps | time per step [us] | real-time factor |", "|---|---|---|---|---|",
            *[f"| {x['scenario']} | {x['estimator']} | {x['steps']} | {x['us_per_step']:.0f} "
              f"| {x['realtime_factor']:.0f} |" for x in r['estimators']],
            "", "Real-time factor: the run time covered by the estimates over the compute time. Target: the particle "
            "filter at 1000 particles faster than real time on the Newcom++ scenarios: "
            f"{_met(all(x['realtime_factor'] > 1 for x in r['estimators'] if x['estimator'].startswith('particle')))}.",
        ]
    path.write_text("\n".join(lines) + "\n")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--previous", required=True, help="commit to compare against (e.g. 5695a5e)")
    parser.add_argument("--repeats", type=int, default=3, help="cold builds of each revision")
    parser.add_argument("--mc-runs", type=int, nargs="+", default=[5, 10, 20],
                        help="run counts of the Monte Carlo cost fit (at least two)")
    parser.add_argument("--mc-repeats", type=int, default=2,
                        help="builds per run count and revision of the Monte Carlo cost fit (the fastest is kept)")
    parser.add_argument("--small", action="store_true", help="one scenario per dataset: a quick test of this script")
    parser.add_argument("--cold-only", action="store_true",
                        help="only the alternating cold builds of both revisions (a reduced run)")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "RESULTS.md")
    args = parser.parse_args()
    if len(args.mc_runs) < 2 or min(args.mc_runs) < 2:
        parser.error("--mc-runs needs at least two run counts, each >= 2 (RSS calibration uses another run)")
    OUT.mkdir(parents=True, exist_ok=True)
    become_subreaper()
    previous = export_revision(args.previous)
    trees = {"current": ROOT, "previous": previous}
    results = {
        "small": args.small, "cold_only": args.cold_only,
        "previous": subprocess.run(["git", "rev-parse", "--short", args.previous], cwd=ROOT, capture_output=True,
                                   text=True, check=True).stdout.strip(),
        "workflow": bench_workflow(trees, args.repeats, args.small),
    }
    if not args.cold_only:
        results.update({
            "filters": bench_filters(args.repeats),
            "estimators": bench_estimators(args.repeats),
            "imports": bench_job_imports(trees),
            "sim": bench_simulator(trees),
            "mc_repeats": args.mc_repeats,
            "scaling": bench_scaling(trees, args.mc_runs, args.mc_repeats, args.small),
        })
    command = "python benchmarks/run.py " + " ".join(sys.argv[1:])
    write(results, args.out, command.strip())
    print(args.out.read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
