"""scripts/probe_inputs.py's machinery on a few cheap cases: a clean refusal, a clean success, a refusal the
case expected to be accepted (not clean), a command that damages a folder it was given (data loss) and
one that accepts what it should refuse (silently wrong). The commands are plain Python, not the
project's: the probe's classification is under test here, not sim."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def probe() -> Any:
    spec = importlib.util.spec_from_file_location("probe_inputs", ROOT / "scripts" / "probe_inputs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["probe_inputs"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


# A tiny argparse command that refuses --phi outside [0, 1] and writes its value into --out/value.txt.
COMMAND = """
import argparse, math, pathlib, sys
parser = argparse.ArgumentParser(prog="tool", allow_abbrev=False)
parser.add_argument("--phi", type=float, required=True)
parser.add_argument("--out", required=True)
args = parser.parse_args()
if not 0 <= args.phi <= 1:
    parser.error(f"--phi must be in [0, 1], got {args.phi}")
out = pathlib.Path(args.out)
out.mkdir(exist_ok=True)
(out / "value.txt").write_text(str(args.phi))
print(args.phi)
"""


def _cases(probe: Any) -> list[Any]:
    Case = probe.Case
    tool = ("@WORK@/tool.py",)
    files = (("tool.py", COMMAND),)
    return [
        Case("refuse-clean", "scripts", "refuse", argv=(*tool, "--phi", "2", "--out", "@OUT@"), files=files,
             needle="--phi"),
        Case("ok-clean", "scripts", "ok", argv=(*tool, "--phi", "0.5", "--out", "@OUT@"), files=files,
             checks=("plausible:",)),
        Case("wrong-expectation", "scripts", "ok", argv=(*tool, "--phi", "7", "--out", "@OUT@"), files=files),
        Case("data-loss", "scripts", "refuse", argv=(*tool, "--phi", "0.5", "--out", "@WORK@/theirs"),
             files=(*files, ("theirs/value.txt", "0.25")), needle="--out"),
        Case("api-accepts", "dipenv API", "refuse", code="import math\nmath.sqrt(4.0)", needle="x"),
        Case("api-refuses", "dipenv API", "refuse", code="raise ValueError('x must be > 0')", needle="x"),
    ]  # fmt: skip


def test_outcomes_are_classified(probe: Any, tmp_path: Path) -> None:
    records = {case.id: probe.run_case(case, tmp_path) for case in _cases(probe)}
    classes = {name: record["class"] for name, record in records.items()}
    assert classes == {
        "refuse-clean": "clean",
        "ok-clean": "clean",
        "wrong-expectation": "escape",  # exit 2 where exit 0 was expected: a valid input refused
        "data-loss": "data loss",  # theirs/value.txt was rewritten
        "api-accepts": "silently wrong",
        "api-refuses": "clean",
    }
    assert "a valid input refused: " in records["wrong-expectation"]["detail"]
    assert "theirs/value.txt" in records["data-loss"]["detail"]
    assert (
        records["refuse-clean"]["exit_code"] == 2 and "error: --phi" in records["refuse-clean"]["stderr_tail"]
    )
    assert "@WORK@" in records["refuse-clean"]["command"]  # paths stay machine-independent
    assert not list((tmp_path / "work").iterdir())  # each case's folder is removed after it


def test_the_report_and_resume(probe: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """main() writes probe.json and probe.md, lists the non-clean cases, and skips recorded cases."""
    cases = _cases(probe)[:3]
    monkeypatch.setattr(probe, "all_cases", lambda: cases)
    out = tmp_path / "out"
    assert probe.main(["--out", str(out), "--scratch", str(tmp_path / "scratch"), "--workers", "2"]) == 0
    data = json.loads((out / "probe.json").read_text())
    assert data["summary"]["counts"] == {"clean": 2, "data loss": 0, "silently wrong": 0, "escape": 1}
    assert [r["id"] for r in data["cases"]] == ["refuse-clean", "ok-clean", "wrong-expectation"]
    report = (out / "probe.md").read_text()
    assert "3 cases: 2 clean, 0 data loss, 0 silently wrong, 1 escape; 66.7% clean." in report
    assert "### wrong-expectation (scripts): escape" in report and "### ok-clean" not in report
    before = (out / "probe.json").read_bytes()
    assert probe.main(["--out", str(out), "--scratch", str(tmp_path / "scratch")]) == 0
    assert (out / "probe.json").read_bytes() == before  # nothing ran again, nothing was added


def test_every_case_is_well_formed(probe: Any) -> None:
    cases = probe.all_cases()
    assert len(cases) >= 150
    assert {c.group for c in cases} == set(probe.GROUPS)
    for case in cases:
        assert (case.argv is None) != (case.code is None), case.id
        assert case.expect in ("refuse", "ok", "either"), case.id
        assert set(case.fixtures) <= set(probe.FIXTURES), case.id
        if case.expect != "ok":
            assert case.needles, f"{case.id}: a refusal must name what it refuses"
        for check in case.checks:
            assert check.partition(":")[0] in probe.CHECKS, case.id
