"""Config and campaign validation: defaults filled in, every error names its key."""

import copy
import re

import pytest
import yaml

from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.validation import validate_config
from wsnloc.errors import ConfigError

from conftest import NEWCOM, ROOT

SCHEMA = ROOT / "config" / "schema.yaml"


@pytest.fixture
def config(monkeypatch):
    monkeypatch.chdir(ROOT)
    return read_yaml(ROOT / "config" / "config.yaml")


def test_shipped_config_is_valid_and_defaults_are_filled(config):
    del config["resample"]
    validate_config(config, SCHEMA)
    assert config["resample"]["rate_hz"] == 5.0
    assert config["datasets"]["newcom"]["source"] == "simulate"


@pytest.mark.parametrize("value", [-1, 0, "20", 2.5])
def test_bad_runs_names_the_key(config, value):
    config["runs"] = value
    with pytest.raises(ConfigError, match=r"config key 'runs'"):
        validate_config(config, SCHEMA)


def test_scenario_runs_set_a_simulated_scenarios_runs_and_name_a_wrong_key(config):
    from wsnloc.workflow import dataset_runs, shards_of

    validate_config(config, SCHEMA)
    runs = config["datasets"]["newcom"]["scenario_runs"]
    assert dataset_runs(config, "newcom", "tdoa") == [f"run-{k:02d}" for k in range(1, runs["tdoa"] + 1)]
    assert len(dataset_runs(config, "newcom", "constant")) == config["runs"]
    config["shards"] = 3
    assert set(shards_of(config, "newcom", "tdoa")) == {f"shard-{k}" for k in range(1, min(3, runs["tdoa"]) + 1)}
    for value, key in (({"tdoa": 0}, r"'datasets.newcom.scenario_runs.tdoa'"),
                       ({"tdao": 2}, r"'datasets.newcom.scenario_runs.tdao': not one of the dataset's scenarios"),
                       ({"tdoa": "2"}, r"'datasets.newcom.scenario_runs.tdoa'")):
        bad = copy.deepcopy(config)
        bad["datasets"]["newcom"]["scenario_runs"] = value
        with pytest.raises(ConfigError, match=key):
            validate_config(bad, SCHEMA)


def test_unknown_top_level_key_is_named(config):
    config["rnus"] = 3
    with pytest.raises(ConfigError, match=r"'rnus': unknown key"):
        validate_config(config, SCHEMA)


def test_unknown_nested_key_is_named_with_its_path(config):
    config["resample"] = {"rate_hz": 5.0, "cutoff": 2}
    with pytest.raises(ConfigError, match=r"'resample.cutoff': unknown key"):
        validate_config(config, SCHEMA)


def test_wrong_enum_names_the_nested_key(config):
    config["datasets"]["newcom"]["source"] = "simulated"
    with pytest.raises(ConfigError, match=r"config key 'datasets.newcom.source'"):
        validate_config(config, SCHEMA)


def test_missing_campaign_file_is_named(config):
    config["datasets"]["newcom"]["campaign"] = "config/campaigns/nowhere.yaml"
    with pytest.raises(ConfigError, match=r"'datasets.newcom.campaign': no such file"):
        validate_config(config, SCHEMA)


def test_logs_source_needs_an_existing_raw_dir(config, tmp_path):
    config["datasets"]["newcom"]["source"] = "logs"
    del config["datasets"]["newcom"]["raw_dir"]
    with pytest.raises(ConfigError, match=r"'datasets.newcom.raw_dir': required"):
        validate_config(config, SCHEMA)
    config["datasets"]["newcom"]["raw_dir"] = str(tmp_path / "missing")
    with pytest.raises(ConfigError, match=r"'datasets.newcom.raw_dir': no such directory"):
        validate_config(config, SCHEMA)


def test_yaml_syntax_error_names_file_and_line(tmp_path):
    bad = tmp_path / "config.yaml"
    bad.write_text("runs: 3\nseed: [1, 2\n")
    with pytest.raises(ConfigError, match=r"config.yaml:\d+: invalid YAML"):
        read_yaml(bad)


def _campaign_with(tmp_path, mutate):
    spec = yaml.safe_load(NEWCOM.read_text())
    mutate(spec)
    path = tmp_path / "campaign.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_campaign_anchor_without_coordinate_is_named(tmp_path):
    path = _campaign_with(tmp_path, lambda s: s["anchors"][0].pop("x"))
    with pytest.raises(ConfigError, match=r"'anchors.0.x': required"):
        Campaign.load(path)


def test_campaign_subset_with_unknown_anchor_is_named(tmp_path):
    path = _campaign_with(tmp_path, lambda s: s["subsets"]["UWB=9"].append("U99"))
    with pytest.raises(ConfigError, match=r"'subsets.UWB=9': unknown anchor 'U99'"):
        Campaign.load(path)


def test_campaign_duplicate_anchor_is_refused(tmp_path):
    path = _campaign_with(tmp_path, lambda s: s["anchors"].append(copy.deepcopy(s["anchors"][0])))
    with pytest.raises(ConfigError, match=r"duplicate anchor id 'U01'"):
        Campaign.load(path)


def test_newcom_campaign_transcribes_the_spec(campaign):
    assert len(campaign.anchors_of("uwb")) == 12
    assert len(campaign.anchors_of("zigbee")) == 21
    subsets = campaign.spec["subsets"]
    assert set(subsets["UWB=12"]) - set(subsets["UWB=9"]) == {"U03", "U08", "U11"}
    assert set(subsets["UWB=12"]) - set(subsets["UWB=10"]) == {"U03", "U11"}
    assert set(subsets["ZigBee=21"]) - set(subsets["ZigBee=17"]) == {"Z02", "Z07", "Z14", "Z19"}
    z = campaign.anchors.set_index("anchor_id")
    assert z.loc["Z01", "y"] == 6.2 and z.loc["Z02", "y"] == 8.8 and z.loc["Z10", "x"] == 28.5


def test_every_model_parameter_has_a_justification():
    """Each numeric leaf under radio/imu/truth is followed by a '#' comment on its line."""
    section = None
    for line in NEWCOM.read_text().splitlines():
        if line and not line.startswith((" ", "#")):
            section = line.split(":")[0]
        stripped = line.strip()
        if section in ("radio", "imu", "truth") and ":" in stripped and not stripped.startswith("#"):
            key, _, value = stripped.partition(":")
            value = value.split("#")[0].strip()
            if value and not value.startswith("{"):
                assert "#" in line, f"no justification for {key!r}: {line!r}"


def test_experiment_on_an_undeclared_scenario_is_named(config):
    config["experiments"]["paper_d"]["scenarios"] = ["newcom/sprint"]
    with pytest.raises(ConfigError, match=r"'experiments.paper_d.scenarios': 'newcom/sprint' is not a declared"):
        validate_config(config, SCHEMA)


@pytest.mark.parametrize("edit, key, value", [
    (lambda c: c["experiments"]["paper_b"]["parameters"].update(anchors="UWB=11"), "experiments.paper_b.parameters.anchors",
     "UWB=11"),
    (lambda c: c["experiments"]["paper_a"]["rows"][3].update(anchors="ZigBee=5"), "experiments.paper_a.rows[3].anchors",
     "ZigBee=5"),
    (lambda c: c["experiments"]["paper_d"]["parameters"].update(anchors="UWB=12+ZigBee=2"),
     "experiments.paper_d.parameters.anchors", "ZigBee=2"),
    (lambda c: c["experiments"]["paper_c"]["table_2_subsets"].append("5: B1..B5"),
     "experiments.paper_c.table_2_subsets[3]", "5: B1..B5"),
])
def test_subset_the_campaign_lacks_is_named(config, edit, key, value):
    edit(config)
    with pytest.raises(ConfigError, match=rf"config key '{re.escape(key)}': '{value}' is not an anchor subset of "
                                          rf"config/campaigns/\w+.yaml"):
        validate_config(config, SCHEMA)


def test_simulated_scenario_the_campaign_lacks_is_named(config):
    config["datasets"]["cricket"]["scenarios"].append("speed_80")
    with pytest.raises(ConfigError, match=r"'datasets.cricket.scenarios': 'speed_80' is not a scenario of "
                                          r"config/campaigns/cricket.yaml (\(did you mean [^)]*\) )?\(defined there: speed_20, speed_40"):
        validate_config(config, SCHEMA)


def test_real_log_scenario_without_runs_is_named(config, tmp_path):
    (tmp_path / "constant" / "run-01").mkdir(parents=True)
    config["datasets"]["newcom"].update(source="logs", raw_dir=str(tmp_path), scenarios=["constant"])
    with pytest.raises(ConfigError, match=r"'datasets.newcom.scenario_runs': only a simulated dataset"):
        validate_config(config, SCHEMA)
    del config["datasets"]["newcom"]["scenario_runs"]
    for experiment in ("paper_a", "paper_b", "paper_d"):
        config["experiments"][experiment]["scenarios"] = ["newcom/constant"]
    config["experiments"]["paper_b"]["simulation_scenarios"] = []
    config["experiments"]["paper_b"]["overrides"] = {"newcom/b_simulation": {"static_start_s": 0.0}}
    config["ranging_validation"]["scenarios"] = ["newcom/constant"]
    config["studies"] = {}
    with pytest.raises(ConfigError, match=r"'experiments.paper_b.overrides.newcom/b_simulation': not a dataset or "
                                          r"dataset/scenario the paper runs on \(newcom/constant\)"):
        validate_config(config, SCHEMA)
    config["experiments"]["paper_b"]["overrides"] = {}
    validate_config(config, SCHEMA)
    config["datasets"]["newcom"]["scenarios"] = ["constant", "variable"]
    with pytest.raises(ConfigError, match=r"'datasets.newcom.scenarios': 'variable' has no run directories"):
        validate_config(config, SCHEMA)


def test_table_2_scenario_outside_the_experiment_is_named(config):
    config["experiments"]["paper_c"]["table_2_scenario"] = "newcom/constant"
    with pytest.raises(ConfigError, match=r"'experiments.paper_c.table_2_scenario': 'newcom/constant' is not one"):
        validate_config(config, SCHEMA)


def test_quarantine_limit_defaults_are_those_of_the_command_line(config):
    from wsnloc.io.limits import DEFAULT_PER_FILE, DEFAULT_PER_RUN

    del config["ingest"]
    validate_config(config, SCHEMA)
    assert config["ingest"] == {"max_quarantine_share": DEFAULT_PER_RUN,
                                "max_quarantine_share_per_file": DEFAULT_PER_FILE}


@pytest.mark.parametrize("paper", ["paper_b", "paper_d"])
def test_nlos_sweep_levels_parse_and_a_bad_level_key_is_named(config, paper):
    validate_config(copy.deepcopy(config), SCHEMA)
    levels = config["experiments"][paper]["nlos_sweep"]["levels"]
    assert levels["spec"] == {} and levels["era_2009"] == {"hardware_class": "ieee802154a_2009"}
    levels["era_2009"]["tap_ns"] = 2.0
    with pytest.raises(ConfigError, match=rf"'experiments\.{paper}\.nlos_sweep\.levels\.era_2009\.tap_ns': unknown key"):
        validate_config(config, SCHEMA)


def test_nlos_sweep_default_is_on_and_its_levels_are_campaign_classes(config):
    from wsnloc.analysis.nlos_severity import level_campaign

    campaign = Campaign.load(NEWCOM)
    for paper in ("paper_b", "paper_d"):
        sweep = config["experiments"][paper]["nlos_sweep"]
        assert sweep["runs"] >= 2          # paper D's other_run RSS calibration needs a donor run
        for name, level in sweep["levels"].items():
            level_campaign(campaign, level, f"experiments.{paper}.nlos_sweep.levels.{name}")


def test_misspelled_key_and_enum_value_get_did_you_mean(config):
    config["rnus"] = 3
    with pytest.raises(ConfigError, match=r"'rnus': unknown key \(did you mean 'runs'\?\)"):
        validate_config(config, SCHEMA)
    del config["rnus"]
    config["datasets"]["newcom"]["source"] = "simulat"
    with pytest.raises(ConfigError, match=r"'datasets.newcom.source': .*did you mean 'simulate'\?"):
        validate_config(config, SCHEMA)


def test_misspelled_estimator_and_parameter_get_did_you_mean(config):
    config["studies"]["workbench"]["estimators"]["ekf"] = {"range_sigma": 0.2}
    with pytest.raises(ConfigError, match=r"'studies.workbench.estimators.ekf.range_sigma': unknown parameter "
                                          r"\(did you mean 'range_sigma_m'"):
        validate_config(config, SCHEMA)
    config["studies"]["workbench"]["estimators"]["ekf"] = {"estimator": "trackr"}
    with pytest.raises(ConfigError, match=r"'studies.workbench.estimators.ekf.estimator': unknown estimator 'trackr' "
                                          r"\(did you mean 'tracker'"):
        validate_config(config, SCHEMA)


def test_unlike_names_get_no_suggestion(config):
    config["studies"]["workbench"]["estimators"]["ekf"] = {"zzz_qqq": 1}
    with pytest.raises(ConfigError) as error:
        validate_config(config, SCHEMA)
    assert "did you mean" not in str(error.value) and "unknown parameter (this estimator has:" in str(error.value)


def test_dataset_kind_defaults_from_source_and_must_fit_it(config):
    validate_config(config, SCHEMA)
    assert config["datasets"]["newcom"]["kind"] == "simulated"
    config["datasets"]["newcom"]["kind"] = "measured"
    with pytest.raises(ConfigError, match=r"'datasets.newcom.kind': 'measured' does not fit source 'simulate'"):
        validate_config(config, SCHEMA)


def test_ranging_validation_scenario_must_be_declared(config):
    config["ranging_validation"] = {"scenarios": ["newcom/constnt"]}
    with pytest.raises(ConfigError, match=r"'ranging_validation.scenarios': 'newcom/constnt' is not a declared"):
        validate_config(config, SCHEMA)
    config["ranging_validation"] = {"scenarios": ["cricket/speed_20"]}
    with pytest.raises(ConfigError, match=r"'ranging_validation.scenarios': the campaign of 'cricket/speed_20' has no"):
        validate_config(config, SCHEMA)
