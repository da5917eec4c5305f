"""The config's JSON Schema judges every config as the loader does."""

from __future__ import annotations

import jsonschema
import pytest
import yaml

from lakegate.lake.config import (
    ConfigError,
    load_config,
)
from lakegate.lake.config_schema import json_schema
from tests.lake.config_files import FIXTURE, write

# -- the JSON Schema agrees with the loader ----------------------------------------------


@pytest.fixture(scope="module")
def validator() -> jsonschema.Draft202012Validator:
    schema = json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def test_fixture_is_valid_under_the_json_schema(validator):
    assert list(validator.iter_errors(yaml.safe_load(FIXTURE.read_text()))) == []


M = "{type: test, description: d, query_string: SELECT 1, template: line"

# Each config is judged the same by the loader and the JSON Schema (True: valid).
AGREEMENT = [
    (True, "version: 1\n"),
    (True, "version: 1\ntopics:\nmetrics:\nmetrics sets:\n"),
    (True, "version: 1\ntopics: {t: {event: true, schema: {a: bigint, b: 'string[]'}}}\n"),
    (True, f"version: 1\nmetrics: {{M: {M}, status: {{query_string: 'SELECT ?', block: 1.5, warn: 2}}}}}}\n"),
    (True, f"version: 1\nmetrics: {{M: {M}, skip_if_no_data: true, template_settings: {{a: 1}}, units: s}}}}\n"),
    (
        True,
        "version: 1\nmetrics: {M: {type: report, description: d, query_string: x, template_type: custom, "
        "template_file: f.json}}\n",
    ),
    (True, "version: 1\ndashboards: {D: {any: [thing]}}\nglobal: {skip-if-no-data: true}\n"),
    (False, "version: 1\nglobal: {x: 1}\n"),
    (False, "version: 1\nglobal: {skip-if-no-data: 1}\n"),
    (False, "topics: {}\n"),
    (False, "version: 2\n"),
    (False, "version: 1\nextra: 1\n"),
    (False, "version: 1\ntopics: {a/b: {schema: {}}}\n"),
    (False, "version: 1\ntopics: {_a: {schema: {}}}\n"),
    (False, "version: 1\ntopics: {METADATA: {schema: {}}}\n"),
    (False, "version: 1\ntopics: {t: {}}\n"),
    (False, "version: 1\ntopics: {t: {schema: {x: flaot}}}\n"),
    (False, "version: 1\ntopics: {t: {schema: {timestamp: int}}}\n"),
    (False, "version: 1\ntopics: {t: {event: yes-please, schema: {}}}\n"),
    (False, "version: 1\ntopics: {t: {schema: [x]}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, querystring: x}}}}\n"),
    (False, "version: 1\nmetrics: {M: {type: test, description: d, template: line}}\n"),
    (False, "version: 1\nmetrics: {M: {type: test, description: d, query_string: ' ', template: line}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, status: {{query_string: 'SELECT ?'}}}}}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, status: {{query_string: 'SELECT ?', block: true}}}}}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, status: {{query_string: 'SELECT ?', block: '0.5'}}}}}}\n"),
    (False, "version: 1\nmetrics: {M: {type: test, description: d, query_string: x}}\n"),
    (False, "version: 1\nmetrics: {M: {type: test, description: d, query_string: x, template_type: custom}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, template_file: f.json}}}}\n"),
    (False, "version: 1\nmetrics: {M: {type: tset, description: d, query_string: x, template: line}}\n"),
    (False, "version: 1\nmetrics: {M: {type: test, description: d, query_string: x, template: lines}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}, skip_if_no_data: 'no'}}}}\n"),
    (False, f"version: 1\nmetrics: {{M: {M}}}}}\nmetrics sets: {{S: {{metrics: [M, M]}}}}\n"),
    (False, "version: 1\nmetrics sets: {S: {metrics: Robot Speed}}\n"),
    (False, "version: 1\nmetrics sets: {S: {}}\n"),
    (False, "version: 1\ndashboards: [a]\n"),
]


@pytest.mark.parametrize(("valid", "text"), AGREEMENT)
def test_loader_and_json_schema_agree(tmp_path, validator, valid, text):
    path = write(tmp_path, text)
    try:
        load_config(path, strict=True)  # the JSON Schema is the strict form: warnings are findings too
        loader_valid = True
    except ConfigError:
        loader_valid = False
    schema_valid = validator.is_valid(yaml.safe_load(text))
    assert (loader_valid, schema_valid) == (valid, valid)
