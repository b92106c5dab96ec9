"""The frame budget from Python: the command line's table as Python data."""

import json

import pyfem2d


def test_budget_returns_the_cli_table_as_data(fem2d, tmp_path):
    args = dict(duration=0.05, energies=["neo-hookean"], frameworks=["explicit", "implicit"])
    messages = []
    ours = pyfem2d.budget("case-a", progress=messages.append, **args)
    out = tmp_path / "budget"
    fem2d(
        "budget", "case-a", "--duration", "0.05", "--energies", "neo-hookean",
        "--frameworks", "explicit,implicit", "--out", str(out),
    )
    cli = json.loads((out / "budget.json").read_text())
    # The same table: keys, scene, frames, reference, rows (their order and settings depend
    # on timings, which differ between two runs; the frameworks compared do not).
    assert set(ours) - {"markdown"} == set(cli)
    for key in ("scene", "fps", "budget_ms", "frames", "reference", "rank_by", "criterion"):
        assert ours[key] == cli[key], key
    assert sorted(r["framework"] for r in ours["rows"]) == sorted(r["framework"] for r in cli["rows"])
    assert ours["references"][0]["windows"] == cli["references"][0]["windows"]
    assert "| " in ours["markdown"]
    assert any("wall time" in m for m in messages)


def test_the_example_runs(tmp_path):
    import runpy
    import sys
    from pathlib import Path

    example = Path(__file__).resolve().parents[3] / "examples" / "python" / "tour.py"
    argv = sys.argv
    sys.argv = [str(example), "--quick", "--out", str(tmp_path)]
    try:
        runpy.run_path(str(example), run_name="__main__")
    finally:
        sys.argv = argv
