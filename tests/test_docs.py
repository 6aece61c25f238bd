"""The docs agree with the code: the README stays short, config/README.md documents every key
of config/schema.yaml (and no other), docs/raw-formats.md the generic format's columns and the
`tech` labels the code gives a meaning."""

import re

import pytest
import yaml

from conftest import ROOT
from wsnloc.analysis.static_bounds import RSS_TECH
from wsnloc.io.generic import COLUMNS
from wsnloc.report.figures import TECH_STYLE

CONFIG_README = (ROOT / "config" / "README.md").read_text()
RAW_FORMATS = (ROOT / "docs" / "raw-formats.md").read_text()
SCHEMA = yaml.safe_load((ROOT / "config" / "schema.yaml").read_text())


def test_readme_is_at_most_8_kb():
    assert len((ROOT / "README.md").read_bytes()) <= 8 * 1024


def test_readme_links_point_to_files_that_exist():
    text = (ROOT / "README.md").read_text()
    for target in re.findall(r"\]\(([^)#]+)\)", text):
        assert (ROOT / target).exists(), target


def key_rows() -> dict[str, str]:
    """{key: its row} of the top-level keys table of config/README.md."""
    section = CONFIG_README.split("## `config/config.yaml`: top-level keys", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        if m := re.match(r"\| ((?:`\w+`(?:, )?)+) \|", line):
            for key in re.findall(r"`(\w+)`", m.group(1)):
                rows[key] = line
    return rows


def sub_keys(spec: dict) -> list[str]:
    """Second-level keys of a top-level schema entry (a mapping of named entries: their fields)."""
    if "properties" in spec:
        return list(spec["properties"])
    named = spec.get("additionalProperties")
    return list(named.get("properties", {})) if isinstance(named, dict) else []


def test_config_readme_documents_exactly_the_schemas_top_level_keys():
    assert set(key_rows()) == set(SCHEMA["properties"])


@pytest.mark.parametrize("key", sorted(SCHEMA["properties"]))
def test_config_readme_row_names_each_of_the_keys_fields(key):
    row = key_rows()[key]
    missing = [field for field in sub_keys(SCHEMA["properties"][key]) if f"`{field}`" not in row]
    assert not missing, f"config/README.md, row `{key}`: {missing} not documented"


def test_config_readme_points_to_this_repositorys_format_spec():
    assert "shared/spec" not in CONFIG_README and "docs/raw-formats.md" in CONFIG_README


@pytest.mark.parametrize("table", sorted(COLUMNS))
def test_raw_formats_lists_the_generic_formats_columns(table):
    line = next(line for line in RAW_FORMATS.splitlines() if line.startswith(f"- `{table}.csv`:"))
    columns = re.sub(r"\([^)]*\)", "", line.split(":", 1)[1]).replace("[", "").replace("]", "")
    required, optional = COLUMNS[table]
    assert [c.strip() for c in columns.split(",")] == required + optional, line
    assert all(f"[, {c}" in line for c in optional), line       # the optional ones marked as such


def test_raw_formats_documents_the_tech_labels_the_code_reads():
    tech = RAW_FORMATS.split("`tech` names", 1)[1].split("\n- ", 1)[0]
    for label in {RSS_TECH, *TECH_STYLE}:
        assert f"`{label}`" in tech, label
