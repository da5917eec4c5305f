"""Per-branch config versions."""

from __future__ import annotations

import subprocess
import sys

import pytest

from lakegate.lake import paths
from lakegate.lake.branch_configs import BranchConfigs
from lakegate.lake.config import Config, Topic
from lakegate.lake.storage import LocalOnlyError

ODOM = "version: 1\ntopics:\n  odom:\n    schema: {x: float}\n"
ODOM_Z = "version: 1\ntopics:\n  odom:\n    schema: {x: float, z: float}\n"
METRICS = (
    "version: 1\nmetrics:\n  Count:\n    type: test\n    description: rows\n"
    "    query_string: SELECT COUNT(*) FROM odom\n"
    "    template_type: system\n    template: scalar\n"
)


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_empty_branch_has_no_config(tmp_path):
    configs = BranchConfigs(tmp_path / "lake", "main")
    assert configs.versions() == [] and configs.current() is None and configs.current_version() is None
    with pytest.raises(KeyError):
        configs.load(1)


def test_store_numbers_versions_keeps_old_ones_and_skips_identical(tmp_path):
    configs = BranchConfigs(tmp_path / "lake", "feature/x")
    first = write(tmp_path, "a.yaml", ODOM)
    assert configs.store([first]) == 1
    assert configs.store([first]) == 1  # identical: no new version
    copy = write(tmp_path, "copy.yaml", ODOM)
    assert configs.store([copy]) == 1  # same content under another name is the same config
    first.write_text(ODOM_Z)
    assert configs.store([first]) == 2
    assert configs.versions() == [1, 2]
    assert list(configs.load(1).topics["odom"].fields) == ["x"]
    assert list(configs.current().topics["odom"].fields) == ["x", "z"]
    assert configs.current_version() == 2
    first.write_text(ODOM)  # back to the first content: a new current version
    assert configs.store([first]) == 3 and list(configs.current().topics["odom"].fields) == ["x"]
    assert (paths.configs_dir(tmp_path / "lake", "feature/x")).parent.name == "feature%2Fx"


def test_several_files_are_merged_in_order(tmp_path):
    configs = BranchConfigs(tmp_path / "lake", "main")
    topics, metrics = write(tmp_path, "config.resim.yaml", ODOM), write(tmp_path, "more.yaml", METRICS)
    version = configs.store([topics, metrics])
    config = configs.current()
    assert set(config.topics) == {"odom"} and set(config.metrics) == {"Count"}
    assert [p.name for p in configs.files(version)] == ["00-config.resim.yaml", "01-more.yaml"]
    assert configs.store([metrics, topics]) == version + 1  # another order is another version


def test_a_config_built_in_code_is_stored_as_its_topics(tmp_path):
    configs = BranchConfigs(tmp_path / "lake", "main")
    config = Config(
        topics={
            "odom": Topic("odom", {"x": "float", "n": "int"}),
            "goal reached": Topic("goal reached", {"tags": "string[]", "metrics": "metric[]"}, event=True),
        }
    )
    version = configs.store_config(config)
    loaded = configs.load(version)
    assert {name: (t.fields, t.event) for name, t in loaded.topics.items()} == {
        "odom": ({"x": "float", "n": "int"}, False),
        "goal reached": ({"tags": "string[]", "metrics": "metric[]"}, True),
    }
    assert configs.store_config(config) == version


def test_concurrent_stores_never_share_a_number(tmp_path):
    lake = tmp_path / "lake"
    sources = [
        write(tmp_path, f"c{i}.yaml", f"version: 1\ntopics:\n  t{i}:\n    schema: {{x: int}}\n") for i in range(6)
    ]
    script = (
        "import sys; from lakegate.lake.branch_configs import BranchConfigs\n"
        "print(BranchConfigs(sys.argv[1], 'main').store([sys.argv[2]]))"
    )
    procs = [
        subprocess.Popen([sys.executable, "-c", script, str(lake), str(s)], stdout=subprocess.PIPE, text=True)
        for s in sources
    ]
    numbers = sorted(int(p.communicate()[0]) for p in procs)
    assert numbers == [1, 2, 3, 4, 5, 6]
    configs = BranchConfigs(lake, "main")
    assert configs.versions() == numbers
    assert sorted(next(iter(configs.load(n).topics)) for n in numbers) == [f"t{i}" for i in range(6)]
    assert not [p for p in paths.configs_dir(lake, "main").iterdir() if p.name.startswith("_")]


def test_a_file_uri_lake_has_the_versions_of_its_path(tmp_path):
    stored = BranchConfigs(tmp_path / "lake", "main").store([write(tmp_path, "a.yaml", ODOM)])
    by_uri = BranchConfigs((tmp_path / "lake").as_uri(), "main")
    assert by_uri.versions() == [stored] and list(by_uri.current().topics["odom"].fields) == ["x"]


def test_versions_are_stored_on_a_lake_that_is_not_local_and_loading_one_is_refused(tmp_path):
    configs = BranchConfigs("mock:///bucket/lake", "feature/x")
    first, second = write(tmp_path, "a.yaml", ODOM), write(tmp_path, "b.yaml", ODOM_Z)
    assert [configs.store([first]), configs.store([first]), configs.store([second])] == [1, 1, 2]
    assert configs.versions() == [1, 2]
    assert [e.name for e in configs.storage.list(configs.storage.path("feature%2Fx", "_configs"))] == [
        "v000001",
        "v000002",
    ]
    with pytest.raises(LocalOnlyError, match="object-store lakes are not supported yet: loading a stored config"):
        configs.current()
