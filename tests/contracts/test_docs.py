"""data_contracts/README.md is generated from the contracts and must stay in sync."""

from pathlib import Path

from data_contracts._docs import render_markdown


def test_readme_matches_the_contracts():
    readme = Path(__file__).resolve().parents[2] / "data_contracts" / "README.md"
    assert readme.read_text(encoding="utf-8") == render_markdown(), (
        "run: python -m data_contracts._docs > data_contracts/README.md"
    )
