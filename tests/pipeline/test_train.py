"""The training pipeline from Python: its settings' order of precedence, and the stages it runs."""

import pytest

from hrr_garment.errors import InputError
from hrr_garment.pipeline.train import TrainCallback, TrainSettings, train_model
from hrr_garment.sim.preset import load_preset


class _Heard(TrainCallback):
    def __init__(self):
        self.messages, self.stages = [], []

    def on_message(self, text):
        self.messages.append(text)

    def on_stage_end(self, stage, result):
        self.stages.append(stage)


def test_settings_come_from_the_defaults_then_the_preset_then_the_file_then_the_overrides(tmp_path):
    tiny = load_preset("tiny")
    default = TrainSettings.load()
    preset = TrainSettings.load(tiny)
    assert (
        default.autoencoder.channels
        != preset.autoencoder.channels
        == tuple(tiny.train["autoencoder"]["model"]["channels"])
    )
    config = tmp_path / "cfg.yaml"
    config.write_text("autoencoder:\n  train: {epochs: 7, max_minutes: 2.0}\n")
    user = TrainSettings.load(tiny, config)
    assert user.autoencoder_train.epochs == 7 and user.autoencoder.channels == preset.autoencoder.channels
    flags = TrainSettings.load(
        tiny,
        config,
        {"autoencoder": {"train": {"max_minutes": 0.5}}, "codespace": {"train": {"validation": "windows"}}},
    )
    assert flags.autoencoder_train.max_minutes == 0.5 and flags.autoencoder_train.epochs == 7
    assert flags.codespace_train.validation == "windows"


def test_the_auto_modes_allowance_is_a_setting_and_a_bad_one_names_its_file(tmp_path):
    assert TrainSettings.load().auto.allowance == 1.05
    config = tmp_path / "cfg.yaml"
    config.write_text("auto: {allowance: 1.1}\n")
    assert TrainSettings.load(load_preset("quick"), config).auto.allowance == 1.1
    config.write_text("auto: {allowance: 0.9}\n")  # below the most accurate PVE: nothing could be chosen
    with pytest.raises(InputError, match="cfg.yaml.*allowance"):
        TrainSettings.load(None, config)


def test_the_old_section_name_is_heard_and_bad_settings_name_their_file(tmp_path):
    old = tmp_path / "old.yaml"
    old.write_text("codebook:\n  train: {epochs: 3}\n")
    heard = _Heard()
    assert TrainSettings.load(None, old, callback=heard).codespace_train.epochs == 3
    assert any("'codebook' is now called 'codespace'" in m for m in heard.messages)
    bad = tmp_path / "bad.yaml"
    bad.write_text("autoencoder:\n  train: {no_such_setting: 1}\n")
    with pytest.raises(InputError, match="bad.yaml"):
        TrainSettings.load(None, bad)
    with pytest.raises(InputError, match="expected a mapping"):
        TrainSettings.load(None, None, {"decoder": {}})


def test_unknown_stages_and_missing_datasets_are_refused_before_any_work(tmp_path):
    with pytest.raises(ValueError, match="unknown stage"):
        train_model(tmp_path / "none.h5", tmp_path / "model", TrainSettings(), stages=("train",))
    with pytest.raises(InputError, match="no such dataset"):
        train_model(tmp_path / "none.h5", tmp_path / "model", TrainSettings(), stages=("simulate",))
    heard = _Heard()
    with pytest.raises(InputError, match="no dataset; make it with: hrr-simulate"):
        train_model(
            tmp_path / "none.h5", tmp_path / "model", TrainSettings(), stages=("autoencoder",), callback=heard
        )
    assert heard.stages == [] and not (tmp_path / "model").exists()
