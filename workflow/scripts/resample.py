"""Snakemake adapter: resample each run's IMU table to a uniform low rate."""

from pathlib import Path

from wsnloc.io import tables
from wsnloc.signal.resample import resample_imu
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "resample")
out = Path(sm.output.imu_5hz)
out.mkdir(parents=True, exist_ok=True)
for run_dir in sorted(p for p in Path(sm.input.tables).iterdir() if p.is_dir()):
    imu = tables.read(run_dir / "imu.parquet")
    low = resample_imu(imu, sm.params.rate_hz, sm.params.grid_rate_hz, sm.params.max_gap_s, sm.params.kaiser_beta)
    tables.write("imu_5hz", low, out / f"{run_dir.name}.parquet",
                 {"rate_hz": sm.params.rate_hz, "kaiser_beta": sm.params.kaiser_beta})
    log.info("%s: %d raw samples -> %d at %g Hz (%d in gaps)", run_dir.name, len(imu), len(low),
             sm.params.rate_hz, int(low["in_gap"].sum()))
