"""Study protocols: the example file, each participant's schedule, and every refusal."""

from __future__ import annotations

import copy
import json
import os
import tomllib
from dataclasses import replace
from pathlib import Path

import pytest

from mirror_avatar.common.constraints import REQUIRED
from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.balance import block_balance
from mirror_avatar.lab.design.checker import ProtocolKeyError
from mirror_avatar.lab.design.online import panel_values
from mirror_avatar.lab.design.protocol import MAX_PROTOCOL_BYTES, load_protocol, parse_protocol
from mirror_avatar.lab.design.protocol_keys import TABLES, key_tables
from mirror_avatar.lab.running.messages import Answer, parse_participant_message
from mirror_avatar.realtime.messages import ProtocolError

EXAMPLE = Path(__file__).parents[2] / "examples" / "protocol.toml"


def _example() -> dict:
    return tomllib.loads(EXAMPLE.read_text())


def test_the_example_protocol_loads():
    protocol = load_protocol(EXAMPLE)
    assert protocol.seed == 20261125
    assert [block.name for block in protocol.blocks] == ["alone", "partners"]
    assert protocol.people == ("P1", "P2")
    assert protocol.questions["confidence"].points == 7
    assert protocol.questions["partner"].options == ("a person", "a computer")
    follow = protocol.blocks[1].conditions[0]
    plan = follow.plan({}, seed=5)
    assert plan.roles == ("follower", "leader")
    assert (plan.trials, plan.duration, plan.pause, plan.seed) == (2, 30.0, 5.0, 5)
    assert follow.after_trial == ("partner", "confidence")
    assert (follow.delay, follow.occlude) == (0.0, ())
    assert [(p.sample, p.player, p.change) for p in follow.perturb] == [
        (667, "A1", "role=follower")
    ]
    lead = protocol.blocks[1].conditions[3]
    assert (lead.delay, lead.occlude) == (0.3, ((10.0, 15.0),))
    assert protocol.blocks[1].conditions[2].occlude == ((0.0, float("inf")),)


def test_person_or_avatar_is_filled_by_the_person_or_the_avatar():
    joint = load_protocol(EXAMPLE).blocks[1].conditions[1]
    as_person = joint.plan({"P2": True}, seed=1)
    as_avatar = joint.plan({"P2": False}, seed=1)
    assert [slot.kind for slot in as_person.slots] == ["human", "human"]
    assert [slot.kind for slot in as_avatar.slots] == ["human", "avatar"]
    assert as_avatar.slots[1].spec == "bundled:slow"
    assert as_avatar.slots[1].label == "P2"


def test_schedules_follow_the_williams_design_and_the_seed():
    protocol = load_protocol(EXAMPLE)
    schedules = [protocol.schedule(p) for p in range(4)]
    assert all(steps[0].name == "solo" for steps in schedules)
    partners = [[step.condition for step in steps[1:]] for steps in schedules]
    for position in range(4):
        assert sorted(order[position] for order in partners) == [0, 1, 2, 3]
    assert schedules == [protocol.schedule(p) for p in range(4)]
    draws = [step.persons["P2"] for steps in schedules for step in steps if step.persons]
    assert set(draws) == {True, False}


@pytest.mark.parametrize("seed", [20261125, 3, 77])
def test_person_or_avatar_draws_are_balanced_across_participants_and_positions(seed):
    protocol = replace(load_protocol(EXAMPLE), seed=seed)
    schedules = [protocol.schedule(p) for p in range(8)]  # the Williams design of 4: 8 a cycle
    for name in ("joint", "lead"):
        people = [next(s.persons["P2"] for s in steps if s.name == name) for steps in schedules]
        assert people.count(True) == people.count(False) == 4, (seed, name, people)
    partners = block_balance(protocol, schedules)[1]
    assert partners.problems() == []
    assert partners.kinds.tolist() == [[2, 2, 2, 2], [2, 2, 2, 2]]  # 2 slots of 4 at a position


def test_who_in_a_pair_meets_the_avatar_is_drawn_from_the_seed():
    protocol = load_protocol(EXAMPLE)
    firsts = {
        next(s.persons["P2"] for s in replace(protocol, seed=seed).schedule(0) if s.name == "joint")
        for seed in range(20)
    }
    assert firsts == {True, False}
    assert protocol.schedule(5) == load_protocol(EXAMPLE).schedule(5)


def test_a_protocol_is_single_blind_unless_it_says_double():
    data = _example()
    assert parse_protocol(data, "p.toml").blind == "single"
    assert parse_protocol(data | {"blind": "double"}, "p.toml").blind == "double"


def test_blind_pages_show_no_metrics_unless_a_condition_asks_and_is_warned():
    """Who led and how long the players moved together may tell a partner's kind."""
    quiet = parse_protocol(_example(), "study.toml")
    joint = quiet.blocks[1].conditions[1]
    assert not joint.plan({"P2": True}, 1).show_metrics
    assert not joint.plan({"P2": False}, 1).show_metrics
    assert quiet.warnings == ()
    shown = parse_protocol(_set(("blocks", 1, "conditions", 1, "show_metrics"), True), "study.toml")
    assert shown.blocks[1].conditions[1].plan({"P2": False}, 1).show_metrics
    assert shown.warnings == (
        "study.toml: blocks[1].conditions[1].show_metrics = true tells the participants who led "
        "and how long they moved together, which may give away a partner's kind: leave it out "
        "to keep them blind",
    )
    alone = _set(("blocks", 0, "conditions", 0, "show_metrics"), True)
    assert parse_protocol(alone, "study.toml").warnings == ()  # no partner to give away


def test_a_protocol_without_a_seed_draws_one():
    data = _example()
    del data["seed"]
    first, second = parse_protocol(data, "p.toml"), parse_protocol(data, "p.toml")
    assert first.seed != second.seed


def _set(path: tuple, value: object) -> dict:
    data = copy.deepcopy(_example())
    node = data
    for key in path[:-1]:  # a table the example lacks is added
        node = node.setdefault(key, {}) if isinstance(key, str) else node[key]
    if value is DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return data


DELETE = object()
C0 = ("blocks", 1, "conditions", 0)
REFUSALS = [
    (("colour",), "blue", "colour: unknown key"),
    (("title",), 3, "title: must be text"),
    (("seed",), 1.5, "seed: 1.5 is not allowed (give a whole number in [0, "),
    (("questions",), [], "questions: must be a table"),
    (
        ("questions", "bad id!"),
        {"text": "x", "kind": "text"},
        "questions.bad id!: 'bad id!' is not",
    ),
    (("questions", "partner", "text"), "", "questions.partner.text: must be text"),
    (("questions", "partner", "colour"), 1, "questions.partner.colour: unknown key"),
    (("questions", "partner", "options"), ["a"], "questions.partner.options: needs two"),
    (("questions", "partner", "options"), ["a", "a"], "questions.partner.options: needs two"),
    (("questions", "partner", "options"), "a", "questions.partner.options: must be a list"),
    (("questions", "partner", "options"), ["a", 2], "questions.partner.options[1]: must be text"),
    (("questions", "confidence", "points"), 7.0, "questions.confidence.points: 7.0 is not all"),
    (("questions", "confidence", "anchors"), ["a"], "questions.confidence.anchors: must name"),
    (("questions", "confidence", "anchors"), ["a", 1], "questions.confidence.anchors[1]: must be"),
    (("blocks",), DELETE, "blocks: must be a list of 1 to"),
    (("blocks",), [], "blocks: must be a list of 1 to"),
    (("blocks", 1), "partners", "blocks[1]: must be a table"),
    (("blocks", 1, "repeat"), 2, "blocks[1].repeat: unknown key"),
    (("blocks", 1, "after_block"), "remarks", "blocks[1].after_block: must be a list of question"),
    (("blocks", 1, "after_block"), ["mood"], "blocks[1].after_block: no question 'mood'"),
    (("blocks", 1, "conditions"), [], "blocks[1].conditions: must be a list of 1 to"),
    ((*C0, "name"), "joint", "blocks[1].conditions[0].name: 'joint' names two conditions"),
    ((*C0, "name"), DELETE, "blocks[1].conditions[0].name: must be text"),
    ((*C0, "speed"), 2, "blocks[1].conditions[0].speed: unknown key"),
    ((*C0, "players"), [], "blocks[1].conditions[0].players: must be a list of 1 to"),
    ((*C0, "players", 1, "label"), "-A", "blocks[1].conditions[0].players[1].label: '-A' is not"),
    ((*C0, "players", 1, "spec"), DELETE, "blocks[1].conditions[0].players[1].spec: an avatar"),
    ((*C0, "players", 0, "spec"), "bundled:slow", "blocks[1].conditions[0].players[0].spec: a per"),
    ((*C0, "players", 0, "device"), "lsl", "blocks[1].conditions[0].players[0].device: 'lsl'"),
    ((*C0, "players", 0, "hand"), "left", "blocks[1].conditions[0].players[0].hand: unknown key"),
    ((*C0, "players", 0), "P1", "blocks[1].conditions[0].players[0]: must be a table"),
    ((*C0, "leaders"), ["P9"], "blocks[1].conditions[0].leaders: must list labels"),
    ((*C0, "leaders"), [], "blocks[1].conditions[0].leaders: leader_follower needs exactly one"),
    ((*C0, "trials"), 1.5, "blocks[1].conditions[0].trials: 1.5 is not allowed (give a whole"),
    ((*C0, "pause"), "long", "blocks[1].conditions[0].pause: 'long' is not allowed (give a num"),
    ((*C0, "delay"), True, "blocks[1].conditions[0].delay: True is not allowed (give a number"),
    (
        (*C0, "partner_view"),
        "equalized",
        "blocks[1].conditions[0].partner_view: 'equalized' is "
        "not allowed (give one of as_arrives, equalised, predicted)",
    ),
    ((*C0, "view_lag"), 0.2, "blocks[1].conditions[0].view_lag: belongs to partner_view = 'equa"),
    ((*C0, "view_horizon"), 0.1, "blocks[1].conditions[0].view_horizon: belongs to partner_view"),
    (
        (*C0, "jitter_distribution"),
        "uniform",
        "blocks[1].conditions[0].jitter_distribution: is "
        "the distribution of a jitter this condition does not have",
    ),
    ((*C0, "occlude"), "half", "blocks[1].conditions[0].occlude: must be a list of [start, end]"),
    ((*C0, "occlude"), [[3, 2]], "blocks[1].conditions[0].occlude[0]: must be [start, end] with"),
    ((*C0, "occlude"), [[1, 2, 3]], "blocks[1].conditions[0].occlude[0]: must be [start, end]"),
    ((*C0, "after_trial"), ["mood"], "blocks[1].conditions[0].after_trial: no question 'mood'"),
    (("analysis",), "rmse", "analysis: must be a table"),
    (("analysis", "test"), "t", "analysis.test: unknown key (known keys: primary, direction"),
    (("analysis", "primary"), "cv", "analysis.primary: 'cv' is not a measure (one of phase_lo"),
    (("analysis", "primary"), ["rmse", 3], "analysis.primary: 3 is not a measure"),
    (("analysis", "primary"), DELETE, "analysis.primary: None is not a measure"),
    (("analysis", "primary"), [], "analysis.primary: must name 1 to 5 measures"),
    (("analysis", "contrast"), ["follow"], "analysis.contrast: must name two different cond"),
    (("analysis", "contrast", 1), "near", "analysis.contrast[1]: 'near' is not a condition (one"),
    (("analysis", "reference"), "lead", "analysis.reference: the contrast names the reference"),
    (("analysis", "contrast"), DELETE, "analysis.contrast: 5 conditions: which one is tested is"),
    (
        ("blocks", 1, "conditions", 2, "graph"),
        "star-ish",
        "blocks[1].conditions[2].graph: 'star-ish' is not one of",
    ),
    (
        ("blocks", 1, "conditions", 2, "graph"),
        [[0, 1], [1, 0]],
        "blocks[1].conditions[2].graph: 2 rows for 4 players",
    ),
    (
        ("blocks", 1, "conditions", 1, "players"),
        [{"label": "P1", "kind": "person"}],
        "blocks[1].conditions[1].players: joint needs exactly two players",
    ),
    (
        ("blocks", 1, "conditions", 1, "players", 0, "label"),
        "P2",
        "blocks[1].conditions[1].players: two players are labelled 'P2'",
    ),
    (
        ("blocks", 1, "conditions", 1, "players", 0),
        {"label": "A9", "kind": "avatar", "spec": "bundled:slow"},
        "blocks[1].conditions[1].players: a lab session needs at least one person when its "
        "person-or-avatar is an avatar",
    ),
    (
        ("blocks", 0, "conditions", 0, "players", 1),
        {"label": "A9", "kind": "avatar", "spec": "bundled:slow"},
        "blocks[0].conditions[0].players: a solo session has people only",
    ),
    (
        ("blocks", 1, "conditions", 2, "players"),
        [{"label": "P1", "kind": "person"}],
        "blocks[1].conditions[2].players: a group needs at least two players",
    ),
    (
        ("blocks", 1, "conditions", 0, "name"),
        "fol\tlow",
        "blocks[1].conditions[0].name: holds the control character '\\t'",
    ),
    (("blocks", 0, "name"), "al\none", "blocks[0].name: holds the control character '\\n'"),
    (("online",), "prolific", "online: must be a table"),
    (("online",), {"panel": ["PROLIFIC_PID"]}, "online.panel: unknown key (known keys: panel_ids"),
    (("online",), {"panel_ids": "PROLIFIC_PID"}, "online.panel_ids: must be a list of at most 8"),
    (("online",), {"panel_ids": ["PROLIFIC-PID"]}, "online.panel_ids[0]: 'PROLIFIC-PID' is not"),
    (("online",), {"panel_ids": ["A", "A"]}, "online.panel_ids[1]: 'A' is not a new query"),
    (("online",), {"completion_code": "C 1"}, "online.completion_code: must be 1-64 letters"),
    (("online",), {"refusal_code": 7}, "online.refusal_code: must be 1-64 letters"),
    (("online",), {"completion_url": "http://x.org/?cc=1"}, "online.completion_url: must be an"),
    (("online",), {"refusal_url": "javascript:alert(1)"}, "online.refusal_url: must be an https"),
    (("online",), {"consent": ""}, "online.consent: must be text of 1 to 10000 characters"),
    (("online",), {"consent": "x" * 10_001}, "online.consent: must be text of 1 to 10000"),
    (("online",), {"instructions": "a\x1b[2Jb"}, "online.instructions: holds the control char"),
    (
        ("online",),
        {"consent": "a", "consent_file": "c.txt"},
        "online.consent: consent and consent_",
    ),
    (
        ("online",),
        {"consent_file": "../consent.txt"},
        "online.consent_file: '../consent.txt' is not",
    ),
    (("online",), {"instructions_file": ".env"}, "online.instructions_file: '.env' is not a file"),
    (("online",), {"consent_file": "absent.txt"}, "online.consent_file: absent.txt: no such file"),
    (
        ("questions", "partner", "options", 0),
        "a \x1b[31mperson",
        "questions.partner.options[0]: holds the control character '\\x1b'",
    ),
]


@pytest.mark.parametrize(("path", "value", "message"), REFUSALS)
def test_each_mistake_is_refused_with_its_key_path_and_a_fix(path, value, message):
    with pytest.raises(InputError) as caught:
        parse_protocol(_set(path, value), "study.toml")
    text = str(caught.value)
    assert text.startswith(f"study.toml: {message}"), text
    assert "\n" not in text
    assert text.endswith(")"), text


TABLE_PATHS = {
    "study": (),
    "question": ("questions", "confidence"),
    "block": ("blocks", 1),
    "condition": C0,
    "player": (*C0, "players", 0),
    "analysis": ("analysis",),
    "online": ("online",),
}
"""Where each table of the example protocol is (a Likert question; a person of a condition)."""


def declared_refusals() -> list[tuple[tuple, object, str]]:
    """Every value a declared key refuses, at that key in the example protocol, and the key path;
    a required key left out too."""
    cases = []
    for table, settings in TABLES.items():
        path = TABLE_PATHS[table]
        where = "".join(f"[{k}]" if isinstance(k, int) else f".{k}" for k in path).lstrip(".")
        for setting in settings:
            key = f"{where}.{setting.key}" if where else setting.key
            if setting.constraint is not None:
                cases += [
                    ((*path, setting.key), value, key) for value in setting.constraint.refused()
                ]
                if setting.default is REQUIRED:
                    cases.append(((*path, setting.key), DELETE, key))
    return cases


@pytest.mark.parametrize(
    ("path", "value", "key"),
    declared_refusals(),
    ids=lambda case: "missing" if case is DELETE else str(case),
)
def test_every_value_a_declared_key_refuses_is_refused_in_one_line_naming_its_path(
    path, value, key
):
    with pytest.raises(ProtocolKeyError) as caught:
        parse_protocol(_set(path, value), "study.toml")
    assert caught.value.key == key
    text = str(caught.value)
    assert text.startswith(f"study.toml: {key}: ") and "\n" not in text and text.endswith(")")


def test_the_lab_guide_tables_every_declared_key():
    guide = (Path(__file__).parents[2] / "docs" / "lab.md").read_text(encoding="utf-8")
    for name, table in key_tables().items():
        assert f"<!-- keys: {name} -->\n{table}<!-- end keys -->" in guide, "run make docs-tables"


def test_file_level_refusals_name_the_file(tmp_path):
    missing = tmp_path / "none.toml"
    with pytest.raises(InputError, match=r"none\.toml: no such file"):
        load_protocol(missing)
    broken = tmp_path / "broken.toml"
    broken.write_text("title = \n")
    with pytest.raises(InputError, match=r"broken\.toml: not valid TOML: .*line 1"):
        load_protocol(broken)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"title = '\xff'\n")
    with pytest.raises(InputError, match=r"binary\.toml: not UTF-8"):
        load_protocol(binary)
    huge = tmp_path / "huge.toml"
    huge.write_text("# " + "x" * MAX_PROTOCOL_BYTES)
    with pytest.raises(InputError, match=r"huge\.toml: .* over the limit"):
        load_protocol(huge)
    pipe = tmp_path / "pipe.toml"
    os.mkfifo(pipe)
    with pytest.raises(InputError, match=r"pipe\.toml: is a named pipe \(FIFO\)"):
        load_protocol(pipe)


def test_answers_are_checked_against_their_question():
    questions = load_protocol(EXAMPLE).questions
    choice, likert, text = questions["partner"], questions["confidence"], questions["remarks"]
    assert choice.problem("a computer") is None
    assert choice.problem("a robot") == "partner: choose one of the options"
    assert likert.problem(1) is None and likert.problem(7) is None
    for bad in (0, 8, "5", True, 5.0):
        assert likert.problem(bad) == "confidence: choose a point from 1 to 7"
    assert text.problem("") is None and text.problem("x" * 100) is None
    assert text.problem("x" * 101) == "remarks: write at most 100 characters"
    assert text.problem(3) == "remarks: write at most 100 characters"


def test_a_free_text_answer_fits_in_one_page_message():
    data = _example()
    data["questions"]["remarks"]["max_chars"] = 121
    with pytest.raises(
        InputError,
        match=r"questions.remarks.max_chars: 121 is not allowed \(give a whole number",
    ):
        parse_protocol(data, "study.toml")


def test_a_page_answer_message_is_parsed_and_bounded():
    answer = parse_participant_message(
        json.dumps({"type": "answer", "trial": 3, "question": "confidence", "value": 5})
    )
    assert answer == Answer(3, "confidence", 5)
    longest = {"type": "answer", "trial": 999, "question": "q" * 32, "value": "\u00e9" * 120}
    assert (
        parse_participant_message(json.dumps(longest, ensure_ascii=False)).value == "\u00e9" * 120
    )
    for bad in (
        {"type": "answer", "trial": 1, "question": "q", "value": True},
        {"type": "answer", "trial": 1, "question": "q", "value": [1]},
        {"type": "answer", "trial": 1, "question": 2, "value": 1},
        {"type": "answer", "trial": -1, "question": "q", "value": 1},
    ):
        with pytest.raises(ProtocolError):
            parse_participant_message(json.dumps(bad))


def test_an_online_table_is_read_and_old_protocols_have_none():
    online = {
        "panel_ids": ["PROLIFIC_PID", "STUDY_ID", "SESSION_ID"],
        "completion_url": "https://app.prolific.com/submissions/complete?cc=C1A2B3C4",
        "refusal_code": "NOFIT123",
    }
    protocol = parse_protocol(_example() | {"online": online}, "study.toml")
    assert protocol.online.panel_ids == ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID")
    assert protocol.online.completion.to_json() == {"code": None, "url": online["completion_url"]}
    assert protocol.online.refusal.to_json() == {"code": "NOFIT123", "url": None}
    assert (protocol.online.consent, protocol.online.instructions) == (None, None)
    empty = load_protocol(EXAMPLE).online
    assert empty.panel_ids == () and not empty.completion and not empty.refusal


@pytest.mark.parametrize(
    ("query", "expected"),
    [
        ({"PROLIFIC_PID": "5f1a2b3c", "other": "x"}, {"PROLIFIC_PID": "5f1a2b3c"}),
        ({"STUDY_ID": "s_1-2"}, {"STUDY_ID": "s_1-2"}),
        ({}, {}),
        ({"PROLIFIC_PID": "../etc/passwd"}, "PROLIFIC_PID must be 1 to 64 letters"),
        ({"PROLIFIC_PID": "a" * 65}, "PROLIFIC_PID must be 1 to 64 letters"),
        ({"STUDY_ID": ""}, "STUDY_ID must be 1 to 64 letters"),
        ({"STUDY_ID": "x y"}, "STUDY_ID must be 1 to 64 letters"),
    ],
)
def test_panel_values_are_safe_identifiers_or_refused(query, expected):
    values = panel_values(("PROLIFIC_PID", "STUDY_ID"), query)
    if isinstance(expected, str):
        assert isinstance(values, str) and values.startswith(expected)
    else:
        assert values == expected


def test_the_pages_text_is_read_from_a_file_beside_the_protocol(tmp_path):
    (tmp_path / "consent.txt").write_text("I agree to\n\n  take part.\n", encoding="utf-8")
    data = _example() | {"online": {"consent_file": "consent.txt", "instructions": "Move.\nStop."}}
    online = parse_protocol(data, str(tmp_path / "study.toml")).online
    assert (online.consent, online.instructions) == ("I agree to\n\n  take part.", "Move.\nStop.")
