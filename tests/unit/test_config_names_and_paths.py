"""Config files by name or path (`fdir_service.paths.config_path`): a name is looked up in config/,
a path is taken as it is, and a folder that happens to carry a config's name (a campaign's --out
folder, say) does not hide the config."""

from __future__ import annotations

from fdir_service.paths import config_dir, config_path
from sim_bridge.scenario import load_scenario


def test_a_name_is_looked_up_and_a_path_is_taken_as_it_is(tmp_path):
    assert config_path("experiments", "real-stuck") == config_dir() / "experiments" / "real-stuck.toml"
    own = tmp_path / "mine"
    own.write_text("")
    assert config_path("experiments", own) == own and config_path("experiments", "x.toml").name == "x.toml"


def test_a_folder_named_like_an_experiment_does_not_hide_it(tmp_path, monkeypatch):
    (tmp_path / "real-stuck").mkdir()          # e.g. `sim-bridge experiment real-stuck --out real-stuck`
    monkeypatch.chdir(tmp_path)
    assert config_path("experiments", "real-stuck") == config_dir() / "experiments" / "real-stuck.toml"
    assert load_scenario("real-stuck").id == "real-stuck"
