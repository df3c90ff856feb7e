"""docs/configuration.md is generated from the configuration tree and kept in step."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from robustrtk.cli.docs import _EXAMPLE, configuration_markdown
from robustrtk.pipeline.config import LEAVES, SECTIONS, flatten_config_dict

DOC = Path(__file__).resolve().parents[2] / "docs" / "configuration.md"


def test_committed_configuration_doc_equals_the_generated_text() -> None:
    assert DOC.read_text(encoding="utf-8") == configuration_markdown(), (
        "docs/configuration.md is stale: python -m robustrtk.cli.docs > docs/configuration.md"
    )


def test_configuration_doc_lists_every_key_with_its_flag_and_default() -> None:
    text = configuration_markdown()
    for key, leaf in LEAVES.items():
        row = next(line for line in text.splitlines() if line.startswith(f"| `{key}` |"))
        assert f"`{leaf.flag}`" in row, key
        assert leaf.help in row, key
    for section in SECTIONS:
        assert f"## [{section}]" in text
    # per-preset defaults where they differ, one value where they agree
    code = next(line for line in text.splitlines() if line.startswith("| `code_sigma_m` |"))
    assert "dpl `0.25`; rtk `0.25`; spp `3`; dgnss `0.3`; rtk (RINEX) `0.3`" in code
    ratio = next(line for line in text.splitlines() if line.startswith("| `ratio` |"))
    assert "| `3` |" in ratio and "| rtk, rtk (RINEX) |" in ratio


def test_the_toml_example_of_the_doc_loads() -> None:
    import tomllib

    flat = flatten_config_dict(tomllib.loads(_EXAMPLE))
    assert flat["ratio"] == 2.5 and flat["systems"] == "GE" and flat["mode"] == "rtk"
    assert "```toml\n" + _EXAMPLE.rstrip("\n") + "\n```" in configuration_markdown()


def test_module_entry_point_prints_the_doc() -> None:
    import os

    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2] / "src"))
    out = subprocess.run(
        [sys.executable, "-m", "robustrtk.cli.docs"], capture_output=True, text=True, check=True, env=env
    )
    assert out.stdout == configuration_markdown()
