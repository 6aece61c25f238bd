"""Converters from public datasets' own layouts into the generic format.

cucudasluv/UWB-dataset (Hanyang University, Apache-2.0): per-anchor ROS exports
`A<id>.csv` (`%time,field.stamp,field.id,field.x,field.y,field.z,field.distanceFromTag,
field.rssi,field.rssi_fp`, stamps in ns) and `trajectory.csv` (`timestamp,x,y,z,
heading_degrees`, RTK-GNSS in the anchors' frame). Each case becomes a generic run
<out>/<los|nlos>/<trajectory>-<case>/ with anchors, ranges, rss and truth CSV files.
The source files are only read.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from wsnloc.errors import IngestError

NS = 1e-9


def _case_dirs(src: Path):
    for trajectory_csv in sorted(src.glob("Dynamic_measurements/*/*/*/trajectory.csv")):
        case = trajectory_csv.parent
        yield case.parents[1].name.lower(), f"{case.parent.name}-{case.name}".lower().replace("_", "-"), case


def convert_cucudasluv(src: str | Path, out: str | Path) -> list[Path]:
    """Convert every dynamic case; returns the run directories written."""
    src, out = Path(src), Path(out)
    written = []
    for scenario, run, case in _case_dirs(src):
        anchors, ranges, rss = [], [], []
        for path in sorted(case.glob("A*.csv"), key=lambda p: int(p.stem[1:])):
            data = pd.read_csv(path)
            if data.empty:
                continue
            anchor_id = path.stem
            first = data.iloc[0]
            anchors.append((anchor_id, "uwb", first["field.x"], first["field.y"], first["field.z"]))
            t = data["field.stamp"].astype("int64") * NS
            ranges.append(pd.DataFrame({"t": t, "anchor_id": anchor_id, "range_m": data["field.distanceFromTag"]}))
            rss.append(pd.DataFrame({"t": t, "anchor_id": anchor_id, "rss_dbm": data["field.rssi"]}))
        if not anchors:
            raise IngestError(f"{case}: no per-anchor A<id>.csv files")
        truth = pd.read_csv(case / "trajectory.csv")
        target = out / scenario / run
        target.mkdir(parents=True, exist_ok=True)
        pd.DataFrame(anchors, columns=["anchor_id", "tech", "x", "y", "z"]).to_csv(target / "anchors.csv", index=False)
        for name, parts in (("ranges", ranges), ("rss", rss)):
            pd.concat(parts).sort_values("t", kind="stable").to_csv(target / f"{name}.csv", index=False,
                                                                    float_format="%.9f")
        pd.DataFrame({"t": truth["timestamp"] * NS, "x": truth["x"], "y": truth["y"]}).to_csv(
            target / "truth.csv", index=False, float_format="%.9f")
        written.append(target)
    if not written:
        raise IngestError(f"{src}: no Dynamic_measurements/*/*/*/trajectory.csv found")
    return written
