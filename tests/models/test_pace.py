"""The pace regressor: caption embedding -> m/s, a clipped linear map with checked inputs."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from motion_env.models.pace import PaceConfig, PaceRegressor


def test_the_pace_is_a_linear_map_clipped_to_zero_and_max_pace() -> None:
    model = PaceRegressor(PaceConfig(text_dim=3, max_pace=4.0))
    model.set_weights(np.array([1.0, -1.0, 0.0]), 0.5)
    emb = np.array([[1.0, 0.0, 7.0], [0.0, 2.0, 0.0], [9.0, 0.0, 0.0]], np.float32)
    np.testing.assert_allclose(model.pace(emb), [1.5, 0.0, 4.0])
    np.testing.assert_allclose(model.pace(torch.from_numpy(emb)), [1.5, 0.0, 4.0])


def test_bad_settings_and_inputs_say_what_is_wrong() -> None:
    with pytest.raises(ValueError, match="text_dim"):
        PaceConfig(text_dim=0)
    with pytest.raises(ValueError, match="max_pace"):
        PaceConfig(max_pace=0.0)
    model = PaceRegressor(PaceConfig(text_dim=4))
    with pytest.raises(ValueError, match=r"\(N, 4\) caption embeddings"):
        model.pace(np.zeros((2, 5)))
    with pytest.raises(ValueError, match="finite"):
        model.set_weights(np.full(4, np.nan), 0.0)


def test_a_hidden_layer_is_optional_and_set_weights_is_for_the_linear_map_only() -> None:
    linear = PaceRegressor(PaceConfig(text_dim=4))
    assert linear.hidden is None  # the shipped pace.pt: a linear map, as its config says
    model = PaceRegressor(PaceConfig(text_dim=4, hidden=3, max_pace=2.0))
    with torch.no_grad():
        model.linear.bias.fill_(9.0)
    np.testing.assert_allclose(model.pace(np.zeros((2, 4), np.float32)), [2.0, 2.0])  # clipped
    with pytest.raises(ValueError, match="hidden layer"):
        model.set_weights(np.zeros(4), 0.0)
    with pytest.raises(ValueError, match="hidden"):
        PaceConfig(hidden=-1)
