"""The shipped training recipes: each names exactly the settings its shipped weights record."""

from __future__ import annotations

import pytest

from navigan import checkpoint as ckpt
from navigan import config, recipes
from navigan.data import SPLITS

#: Each shipped recipe and the shipped weights it made, with the overrides their commands gave.
MADE: dict[str, list[tuple[str, dict[str, int]]]] = {
    "robot": [("navigan-r-all", {})],
    "playback": [(f"navigan-r-{s}", {"epochs": 60} if s == "univ" else {}) for s in SPLITS],
    **{model: [(f"{model}-{s}", {}) for s in SPLITS] for model in ("goal-social-lstm", "navil2", "navigan")},
}


def test_shipped_recipes_cover_every_model():
    assert set(recipes.shipped()) == {*MADE, "paper"}
    assert {recipes.load(name).model for name in recipes.shipped()} == set(config.MODELS)


@pytest.mark.parametrize("name", sorted(MADE))
def test_recipe_matches_the_settings_its_weights_record(name):
    recipe = recipes.load(name)
    for weights, overrides in MADE[name]:
        record = ckpt.load(ckpt.resolve(weights))
        model, train = recipe.configs(record.split["name"], **overrides)
        assert (model, train) == (record.model, record.train), weights


def test_paper_recipe_is_the_papers_settings():
    model, train = recipes.load("paper").configs("eth")
    assert (model.model, model.hidden, model.pair_pool) == ("navigan-r", 32, False)
    assert (train.epochs, train.patience, train.batch, train.lr, train.d_safe) == (500, None, 32, 1e-3, 0.5)
    assert not (train.augment or train.encounters or train.resist_beyond_truth) and train.resist_intention


def test_overrides_replace_only_what_they_set():
    recipe = recipes.load("playback")
    model, train = recipe.configs("eth", epochs=3, patience=None, seed=7)
    assert (train.epochs, train.patience, train.seed, train.batch) == (3, 10, 7, 256) and model.pair_pool


def test_closed_loop_table_sets_the_tuning_and_the_seed_override_wins(tmp_path):
    mine = tmp_path / "mine.toml"
    mine.write_text('model = "navigan-r"\n[closed_loop]\nrounds = 3\nseed = 4\nw_hinge = 20\n')
    recipe = recipes.load(str(mine))
    assert recipe.tuning() == config.ClosedLoopConfig(rounds=3, seed=4, w_hinge=20.0)
    assert recipe.tuning(seed=9) == config.ClosedLoopConfig(rounds=3, seed=9, w_hinge=20.0)
    assert recipes.load("playback").tuning() == config.ClosedLoopConfig()


def test_evasion_table_sets_the_networks_training_and_the_seed_override_wins(tmp_path):
    mine = tmp_path / "mine.toml"
    mine.write_text('model = "navigan-r"\n[evasion]\nrounds = 1\nwidth = 64\nseed = 4\nmargin = 0.6\n')
    recipe = recipes.load(str(mine))
    assert recipe.evasion_training() == config.EvasionConfig(rounds=1, width=64, seed=4, margin=0.6)
    assert recipe.evasion_training(seed=9) == config.EvasionConfig(rounds=1, width=64, seed=9, margin=0.6)
    assert recipes.load("playback").evasion_training() == config.EvasionConfig()
