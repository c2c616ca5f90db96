"""Which detector `usvfast shore` runs by default (usvfast.shore.defaults) and
`usvfast shore-train --detector ssd`: the order of `--detector auto` (fine-tuned SSD, trained
CNN, zero-shot COCO SSD, Bayes) with each option present or absent (stand-in model files: only
the choice is tested here; the export itself is tested in test_shore_ssd.py), the environment
variables, the one stderr note, the errors of `--detector ssd` with nothing usable, and a very
short fine-tuning through the command that `usvfast shore` then picks up by default."""

from __future__ import annotations

import itertools
import json
import shutil
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from usvfast.cli import app
from usvfast.shore import defaults
from usvfast.shore.defaults import (
    COCO_EXPORT_FILE,
    SSD_MODEL_FILE,
    choose_detector,
    coco_card,
    model_kind,
)
from usvfast.shore.pipeline import ShoreConfig

from conftest import shared_data

ENV = ("USVFAST_SHORE_MODEL", "USVFAST_SHORE_SSD_MODEL", "USVFAST_SSD_GRAPH")


@pytest.fixture
def models(tmp_path, monkeypatch) -> Path:
    """An empty user model folder; no model named by the environment; the stderr note unsaid."""
    folder = tmp_path / "models"
    folder.mkdir()
    monkeypatch.setenv("USVFAST_MODELS", str(folder))
    for var in ENV:
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setattr(defaults, "_said", set())
    return folder


def _stand_in(path: Path, card: dict | None = None) -> Path:
    path.write_bytes(b"stand-in: only the choice reads this file")
    if card is not None:
        path.with_suffix(".json").write_text(json.dumps(card))
    return path


def _weights_installed() -> bool:
    try:
        defaults.coco_graph_path(check=False)
    except ValueError:
        return False
    return True


@pytest.mark.parametrize("zero_shot", ["exportable", "cached", "no torch", "no weights"])
def test_auto_takes_the_first_option_present(models, tmp_path, monkeypatch, capsys, zero_shot):
    """Every subset of {fine-tuned SSD, trained CNN} × each state of the zero-shot SSD."""
    if zero_shot == "exportable" and not _weights_installed():
        pytest.fail("the COCO weights (usvfast[pretrained], in the test extra) are missing")
    if zero_shot in ("cached", "no torch"):
        monkeypatch.setitem(sys.modules, "torch", None)  # import torch fails
    if zero_shot == "cached":
        _stand_in(models / COCO_EXPORT_FILE, coco_card())
    if zero_shot == "no weights":
        monkeypatch.setenv("USVFAST_SSD_GRAPH", str(tmp_path / "absent.pb"))
    for ssd, cnn in itertools.product((True, False), repeat=2):
        for f in (SSD_MODEL_FILE, "shore-cnn.onnx"):
            (models / f).unlink(missing_ok=True)
        if ssd:
            _stand_in(models / SSD_MODEL_FILE)
        if cnn:
            _stand_in(models / "shore-cnn.onnx")
        cfg = ShoreConfig()
        assert cfg.choice is not None and cfg.choice.auto
        if ssd:
            want = ("ssd", models / SSD_MODEL_FILE, "fine-tuned SSD")
        elif cnn:
            want = ("cnn", models / "shore-cnn.onnx", "trained CNN")
        elif zero_shot in ("exportable", "cached"):
            want = ("ssd", models / COCO_EXPORT_FILE, "zero-shot COCO SSD-MobileNetV2")
        else:
            want = ("bayes", None, "Bayes detector (no model available)")
        assert (cfg.detector, cfg.choice.model, cfg.choice.weights) == want, (ssd, cnn)
        if want[0] == "ssd":
            assert cfg.ssd_model == want[1]
        if want[0] == "cnn":
            assert cfg.cnn_model == want[1]
    # exporting writes nothing at choice time; only a missing option is said, once
    assert (models / COCO_EXPORT_FILE).exists() == (zero_shot == "cached")
    err = capsys.readouterr().err
    if zero_shot in ("exportable", "cached"):
        assert err == ""
    else:
        assert err.count("using the Bayes detector") == 1
        assert ("torch" in err) if zero_shot == "no torch" else ("not installed" in err)
        assert "usvfast[pretrained]" in err


def test_environment_names_the_models(models, tmp_path, monkeypatch):
    cnn = _stand_in(tmp_path / "my-cnn.onnx")
    ssd = _stand_in(tmp_path / "my-ssd.onnx")
    monkeypatch.setenv("USVFAST_SHORE_MODEL", str(cnn))
    assert (ShoreConfig().detector, ShoreConfig().cnn_model) == ("cnn", cnn)
    monkeypatch.setenv("USVFAST_SHORE_SSD_MODEL", str(ssd))
    c = choose_detector()
    assert (c.detector, c.model, c.auto) == ("ssd", ssd, True)
    assert ShoreConfig(detector="ssd").ssd_model == ssd
    # a named model wins over the choice; auto with --model reads the kind from the card
    assert ShoreConfig(cnn_model=cnn).detector == "cnn"
    assert model_kind(cnn) == "cnn"
    _stand_in(tmp_path / "tuned.onnx", {"layout": "ssd"})
    assert model_kind(tmp_path / "tuned.onnx") == "ssd"
    monkeypatch.setenv("USVFAST_SHORE_SSD_MODEL", str(tmp_path / "missing.onnx"))
    with pytest.raises(ValueError, match="USVFAST_SHORE_SSD_MODEL"):
        ShoreConfig()


def test_detector_ssd_with_nothing_usable_says_what_to_do(models, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "torch", None)
    with pytest.raises(ValueError, match=r"ssd_model: .*shore-train --detector ssd.*torch"):
        ShoreConfig(detector="ssd")
    monkeypatch.setenv("USVFAST_SSD_GRAPH", str(tmp_path / "absent.pb"))
    with pytest.raises(ValueError, match=r"usvfast\[pretrained\]"):
        ShoreConfig(detector="ssd")
    frames = tmp_path / "frames"
    frames.mkdir()
    cv2.imwrite(str(frames / "f_0.png"), np.full((60, 80, 3), 128, np.uint8))
    args = ["shore", str(frames), "--out", str(tmp_path / "out"), "--detector", "ssd"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code != 0 and "shore-train --detector ssd" in res.output
    # a stale cache (another graph) is not used
    _stand_in(models / COCO_EXPORT_FILE, {**coco_card(), "graph_sha256": "0" * 64})
    with pytest.raises(ValueError, match="ssd_model"):
        ShoreConfig(detector="ssd")


def _annotations(folder: Path, video: str, count: int) -> Path:
    src = shared_data("mardct") / "training" / "annotations"
    folder.mkdir()
    pngs = sorted(src.glob(f"{video}_*.png"))[:count]
    for png in pngs:
        shutil.copy(png, folder / png.name)
        shutil.copy(png.with_suffix(".txt"), folder / png.with_suffix(".txt").name)
    return folder


def test_shore_train_ssd_writes_the_model_usvfast_shore_then_uses(models, tmp_path):
    """Two fine-tuning steps on eight views of four MarDCT frames (the wiring, not the
    model's quality: test_shore_ssd.py scores a real fine-tune)."""
    from usvfast.shore.mot import read_mot
    from usvfast.shore.pretrained import SsdDetector
    from usvfast.shore.ssd_train import CONF_GRID

    ann = _annotations(tmp_path / "ann", "2", 4)
    runner = CliRunner()
    args = ["shore-train", str(ann), "--detector", "ssd", "--steps", "2", "--views", "8"]
    res = runner.invoke(app, [*args, "--seed", "3"])
    assert res.exit_code == 0, res.output
    model = models / SSD_MODEL_FILE
    card = json.loads(model.with_suffix(".json").read_text())
    assert card["layout"] == "ssd" and card["videos"] == ["2"]
    assert (card["train"]["steps"], card["train"]["views"], card["train"]["seed"]) == (2, 8, 3)
    assert card["conf_threshold"] in CONF_GRID
    out = tmp_path / "out"
    res = runner.invoke(app, ["shore", str(ann), "--out", str(out), "--no-progress", "--no-video"])
    assert res.exit_code == 0, res.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["detector"] == "ssd" and summary["model"] == str(model)
    assert summary["detector_choice"].startswith("auto: fine-tuned SSD")
    assert "auto: fine-tuned SSD" in res.output
    # the chain's boxes on the first frame are the model's at its card's threshold
    first = sorted(ann.glob("*.png"), key=lambda p: int(p.stem.split("_")[1]))[0]
    det = SsdDetector(model).detect(cv2.imread(str(first), cv2.IMREAD_COLOR))
    rows = read_mot(out / "detections.txt")
    kept = rows[rows[:, 0] == 1, 2:6]
    assert len(kept) >= 1 and summary["detections_raw"] >= len(kept)
    for box in kept:
        assert np.abs(det.boxes - box).max(axis=1).min() < 0.01
    # a model named with --model under auto is run as what its card says
    res = runner.invoke(
        app, ["shore", str(ann), "--out", str(out), "--model", str(model), "--no-progress"]
    )
    assert res.exit_code == 0, res.output
    assert json.loads((out / "summary.json").read_text())["detector"] == "ssd"


def test_shore_train_ssd_bad_input(models, tmp_path):
    runner = CliRunner()
    empty = tmp_path / "empty"
    empty.mkdir()
    cases = [
        ([str(empty), "--detector", "ssd"], "folder"),
        ([str(empty), "--detector", "ssd", "--hard-negatives"], "hard_negatives"),
        ([str(empty), "--detector", "ssd", "--wake-filter"], "wake_filter"),
        ([str(empty), "--detector", "ssd", "--views", "4"], "views"),
        ([str(empty), "--detector", "ssd", "--steps", "0"], "steps"),
        ([str(empty), "--detector", "ssd", "--out", str(tmp_path / "m.onnx")], "out"),
        ([str(empty), "--detector", "cnn", "--views", "100"], "views"),
        ([str(empty), "--detector", "yolo"], "detector"),
    ]
    for args, word in cases:
        res = runner.invoke(app, ["shore-train", *args])
        assert res.exit_code != 0 and word in res.output, (args, res.output)
    assert not any(models.iterdir())
