"""The run-folder protocol (sim.runs.folder): one owner per folder, named in a manifest written first."""

from __future__ import annotations

import json
import math

import pytest

from sim.runs.folder import (
    MANIFEST,
    RunFolderError,
    check_writable_parent,
    claim,
    differing,
    preview,
    read_manifest,
)
from sim.runs.legacy import legacy_command, legacy_markers


def test_new_folder_is_created_and_claimed_with_manifest_first(tmp_path) -> None:
    out = tmp_path / "a" / "b"
    result = claim(out, "sim run", {"mason": math.inf, "n": 10}, argv=["python", "-m", "sim", "run"])
    assert result.state == "new" and (out / MANIFEST).is_file()
    data = json.loads((out / MANIFEST).read_text())
    assert data["command"] == "sim run" and data["params"] == {"mason": "inf", "n": 10}
    assert data["argv"] == ["python", "-m", "sim", "run"] and data["source_digest"] and data["version"]


def test_same_command_and_identity_continues_and_inf_round_trips(tmp_path) -> None:
    claim(tmp_path / "r", "sim flow-curve", {"mason": [1.0, math.inf], "rates": (0.1, 1)})
    again = claim(
        tmp_path / "r", "sim flow-curve", {"mason": [1.0, math.inf], "rates": [0.1, 1]}, resume=True
    )
    assert again.state == "same"


def test_other_command_or_other_parameters_are_refused_naming_folder_and_keys(tmp_path) -> None:
    out = tmp_path / "r"
    claim(out, "sim run", {"mason": 1.0, "seed": 1})
    (out / "result.json").write_text("{}")
    with pytest.raises(RunFolderError, match=r"--out .*r belongs to another command \('sim run'"):
        claim(out, "agents.train", {"seed": 1})
    with pytest.raises(RunFolderError, match=r"mason=1\.0 there, mason=2\.0 requested"):
        claim(out, "sim run", {"mason": 2.0, "seed": 1})
    assert (out / "result.json").exists()  # nothing was deleted


def test_overwrite_removes_the_whole_previous_run(tmp_path) -> None:
    out = tmp_path / "r"
    claim(out, "sim flow-curve", {"mason": [1.0]})
    (out / "sub").mkdir()
    (out / "sub" / "flow_curve.csv").write_text("x")
    (out / "checkpoint.npz").write_text("x")
    result = claim(out, "sim run", {"mason": 2.0}, overwrite=True)
    assert result.state == "overwritten"
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST]
    assert read_manifest(out).command == "sim run"


def test_non_empty_folder_without_manifest_is_refused_even_with_overwrite(tmp_path) -> None:
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    for overwrite in (False, True):
        with pytest.raises(RunFolderError, match=r"not empty \(thesis\.tex\) and holds no manifest\.json"):
            claim(out, "sim run", {}, overwrite=overwrite)
    assert (out / "thesis.tex").read_text() == "precious"


def test_legacy_folder_of_the_same_command_is_adopted(tmp_path) -> None:
    out = tmp_path / "old"
    out.mkdir()
    (out / "sweep.json").write_text("{}")
    result = claim(out, "sim sweep", {"phi": [0.45]}, legacy=("sweep.json",))
    assert result.state == "adopted" and (out / "sweep.json").exists() and (out / MANIFEST).exists()
    other = tmp_path / "old2"  # another command's pre-manifest folder is not adopted
    other.mkdir()
    (other / "sweep.json").write_text("{}")
    with pytest.raises(RunFolderError, match="holds no manifest"):
        claim(other, "sim run", {}, legacy=("params.json",))


def test_resume_needs_a_run_and_excludes_overwrite(tmp_path) -> None:
    with pytest.raises(RunFolderError, match="holds no run to continue"):
        claim(tmp_path / "new", "sim run", {}, resume=True)
    with pytest.raises(RunFolderError, match="exclude each other"):
        claim(tmp_path / "x", "sim run", {}, resume=True, overwrite=True)


def test_allowed_change_is_recorded(tmp_path) -> None:
    out = tmp_path / "r"
    claim(out, "sim run", {"strain": 5.0, "seed": 1})
    longer = claim(
        out,
        "sim run",
        {"strain": 10.0, "seed": 1},
        compare=lambda a, b: [k for k in differing(a, b) if k != "strain"],
    )
    assert longer.state == "same" and read_manifest(out).params["strain"] == 10.0


def test_file_in_place_of_folder_garbage_manifest_and_unwritable_parent(tmp_path) -> None:
    (tmp_path / "f").write_text("x")
    with pytest.raises(RunFolderError, match="exists and is not a folder"):
        claim(tmp_path / "f", "sim run", {})
    (tmp_path / "g").mkdir()
    (tmp_path / "g" / MANIFEST).write_text("{not json")
    with pytest.raises(RunFolderError, match="not a readable manifest"):
        claim(tmp_path / "g", "sim run", {})
    with pytest.raises(RunFolderError, match="exists and is not a folder"):
        check_writable_parent(tmp_path / "f" / "below")
    check_writable_parent(tmp_path / "fine" / "deeper")


def test_preview_tells_what_claim_would_do_and_writes_nothing(tmp_path) -> None:
    """A command checks its folder (and then the files it would continue from) before any work, and claims
    it only once everything is in order: preview raises what claim would raise, and writes nothing."""
    out = tmp_path / "a" / "b"
    assert preview(out, "sim run", {"seed": 1}) == "new" and not (tmp_path / "a").exists()
    with pytest.raises(RunFolderError, match="holds no run to continue .no such folder."):
        preview(out, "sim run", {"seed": 1}, resume=True)
    assert not (tmp_path / "a").exists()  # was: claim made the folder, then refused --resume
    with pytest.raises(RunFolderError, match="holds no run to continue"):
        claim(out, "sim run", {"seed": 1}, resume=True)
    assert not (tmp_path / "a").exists()
    claim(out, "sim run", {"seed": 1})
    (out / "result.json").write_text("{}")
    assert preview(out, "sim run", {"seed": 1}, resume=True) == "same"
    assert preview(out, "sim run", {"seed": 2}, overwrite=True) == "overwritten"
    assert (out / "result.json").exists()
    with pytest.raises(RunFolderError, match="seed=1 there, seed=2 requested"):
        preview(out, "sim run", {"seed": 2})


def test_legacy_folders_of_sim_commands_are_recognised(tmp_path) -> None:
    """Which sim command wrote a folder before manifests: adopted by that command, refused (naming it) by
    the others unless they overwrite it; unknown files are not a sim folder."""
    run, curve, several, sweep, unknown = (tmp_path / n for n in ("run", "curve", "several", "sweep", "x"))
    for folder in (run, curve, several / "Mn1", several / "Mn2", sweep, unknown):
        folder.mkdir(parents=True)
    (run / "params.json").write_text(json.dumps({"config": {}}))
    (curve / "params.json").write_text(json.dumps({"flow_curve": {}}))
    for sub in ("Mn1", "Mn2"):
        (several / sub / "flow_curve.csv").write_text("")
    (sweep / "sweep.json").write_text("{}")
    (unknown / "notes.txt").write_text("")
    found = {f.name: legacy_command(f) for f in (run, curve, several, sweep, unknown, tmp_path / "none")}
    assert found == {
        "run": "sim run",
        "curve": "sim flow-curve",
        "several": "sim flow-curve",
        "sweep": "sim sweep",
        "x": None,
        "none": None,
    }
    assert legacy_markers(run, "sim run", overwrite=False) == ("params.json",)
    assert legacy_markers(several, "sim flow-curve", overwrite=False) == ("Mn1", "Mn2")
    with pytest.raises(RunFolderError, match=r"--out .*curve holds a run of sim flow-curve written before"):
        legacy_markers(curve, "sim run", overwrite=False)
    assert legacy_markers(curve, "sim run", overwrite=True) == ("params.json",)
    assert legacy_markers(unknown, "sim run", overwrite=True) == ()
    claim(curve, "sim run", {}, overwrite=True, legacy=("params.json",))
    assert [p.name for p in curve.iterdir()] == [MANIFEST]
