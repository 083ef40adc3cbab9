"""The message a page builds an avatar's player from (`mirror_avatar.browser.browser_arrays`)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mirror_avatar.browser import browser_arrays
from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.deep.features import count_features
from mirror_avatar.deep.network import count_parameters
from mirror_avatar.dynamics import FOLLOWER
from mirror_avatar.players import Observation, RecordedPlayer, VirtualTrainer
from mirror_avatar.specs import bundled_generator, model_partner
from mirror_avatar.training.imitation import make_cyber_player


def test_a_message_is_json_whose_floats_read_back_bit_for_bit() -> None:
    player = make_cyber_player("follower")
    player.initialise_policy(2)
    text = json.dumps(browser_arrays(player, 0, 10), allow_nan=False)
    q_table = json.loads(text)["arrays"]["q_table"]
    assert q_table["shape"] == list(player.q_table_.shape)
    assert np.array_equal(np.reshape(q_table["data"], q_table["shape"]), player.q_table_)


def test_a_tabular_message_holds_its_cells_actions_and_end_effector() -> None:
    player = make_cyber_player("follower")
    player.initialise_policy(2)
    message = browser_arrays(player, 0, 10)
    arrays, disc = message["arrays"], player.discretisation_
    assert message["kind"] == "cyber" and message["features"] == "relative"
    assert arrays["edges"]["data"] == disc.flat_edges.tolist()
    assert arrays["offsets"]["data"] == disc.offsets.tolist()
    assert arrays["actions"]["data"] == player.actions_.tolist()
    assert message["dynamics"]["omega"] == player.params.omega
    assert message["dynamics"]["n_substeps"] == player.n_substeps
    assert "reference" not in arrays


def test_a_deep_message_holds_its_network_and_input_layout() -> None:
    player = make_cyber_player("leader", bundled_generator("slow"), agent="dqn")
    player.initialise_policy(2)
    message = browser_arrays(player, 0, 10)
    sizes = message["arrays"]["sizes"]["data"]
    assert message["kind"] == "deep" and sizes[0] == count_features(0, True)
    assert message["arrays"]["weights"]["shape"] == [count_parameters(np.array(sizes))]
    assert message["network"]["use_reference"] is True


def test_the_reference_is_the_one_its_reset_draws_from_the_seed() -> None:
    player = make_cyber_player("leader", bundled_generator("slow"))
    player.initialise_policy(2)
    message = browser_arrays(player, 5, 40)
    player.reset(5)
    drawn = []
    for k in range(40):
        player.step(Observation.of_partner(k, 0.0, 0.0, 0.0))
        drawn.append(player.last_reference)
    assert message["arrays"]["reference"]["data"] == drawn
    assert browser_arrays(player, 6, 40)["arrays"]["reference"]["data"] != drawn


def test_without_a_seed_the_entropy_drawn_is_recorded() -> None:
    player = make_cyber_player("leader", bundled_generator("slow"))
    player.initialise_policy(2)
    fresh = browser_arrays(player, None, 20)
    again = browser_arrays(player, int(fresh["seed"]), 20)
    assert fresh["arrays"]["reference"] == again["arrays"]["reference"]


def test_a_recording_sends_its_track_on_the_control_grid() -> None:
    player = RecordedPlayer(load_zhai2017()[0])
    message = browser_arrays(player, 0, 10)
    assert message["kind"] == "recorded" and message["period"] == player.period
    assert message["arrays"]["track"]["shape"] == list(player.track.shape)


@pytest.mark.parametrize(
    ("make", "kind"),
    [
        (lambda: VirtualTrainer(FOLLOWER, bundled_generator("slow")), "VirtualTrainer"),
        (lambda: model_partner("hkb"), "HKBPartner"),
    ],
)
def test_a_player_the_page_cannot_step_is_refused_in_one_line(make, kind: str) -> None:
    with pytest.raises(InputError) as error:
        browser_arrays(make(), 0, 10)
    assert "\n" not in str(error.value)
    assert f"a {kind} cannot be stepped in the browser" in str(error.value)
    assert "run it on the server" in str(error.value)
