"""The keys of a study protocol, declared once: what each sets, allows and defaults to.

Each table of a protocol file (the file itself, a question, a block, a condition, a player) has
its keys declared here as `mirror_avatar.common.constraints.Setting` records. The protocol's reader
(`mirror_avatar.lab.design.protocol`) knows the keys and checks every scalar value from them; the
refusal tests are generated from them; and the lab guide's tables of keys are written from
them (`key_tables`), so that the file format, its checks and its documents say the same.
A condition's trial keys are the plan's (`mirror_avatar.lab.design.plan.TRIAL_SETTINGS`), declared
there once, but for ``show_metrics``, off unless asked (`BLIND_METRICS`); the analysis's primary
measures are the study table's measure columns (`mirror_avatar.metrics.registry.TABLE_COLUMNS`).
"""

from __future__ import annotations

from mirror_avatar.common.constraints import Flag, Interval, Options, Setting, settings_table
from mirror_avatar.lab.design.order import ORDERS
from mirror_avatar.lab.design.plan import CONDITIONS, MAX_PLAYERS, RUNS, SEED_LIMIT, TRIAL_SETTINGS
from mirror_avatar.metrics.registry import TABLE_COLUMNS
from mirror_avatar.realtime.partner_view import HANDLINGS, JITTERS

PLAYER_KINDS = ("person", "avatar", "person-or-avatar")
"""What a protocol's player slot holds."""

QUESTION_KINDS = ("choice", "likert", "text")
"""Kinds of question: one option of several, a point on a rating scale, free text."""

BLINDS = ("single", "double")
"""Who is blind to the partner kinds: the participants' pages, or the researcher's console too."""

MAX_BLOCKS, MAX_CONDITIONS, MAX_QUESTIONS, MAX_OPTIONS = 20, 20, 50, 20
"""Most blocks, conditions per block, questions, and options of a choice."""

MAX_DELAY = 1.0
"""Longest visual delay of the partners (s; Stepp 2009 delayed up to 1 s)."""

MAX_JITTER = 0.25
"""Largest SD of a partner delay's jitter (s; several times a network's, which Rinott et al.
2025 emulated for remote synchrony)."""

MAX_HORIZON = 0.5
"""Longest horizon a partner's position is predicted over (s; dead reckoning's straight line
drifts from a mirror-game movement's curve over a few hundred ms)."""

MAX_ANSWER_CHARS = 120
"""Longest free-text answer (characters; one answer travels in one page message)."""

MAX_OCCLUSION_END = 600.0
"""Latest end of an occlusion interval (s from the trial's start: the longest trial)."""

DIRECTIONS = ("lower", "higher", "two-sided")
"""The directions of a hypothesis: the tested condition's mean lower or higher than the
reference's, or different either way."""

MAX_PRIMARY = 5
"""Most primary measures of an analysis (each a confirmatory test, Holm-corrected together)."""

STUDY_SETTINGS = (
    Setting("title", "the study's name", default="", allowed="text"),
    Setting("seed", "every draw (orders, partners) follows from it",
            Interval(int, 0, SEED_LIMIT), None, default_shown="drawn and recorded"),
    Setting("block_order", "the order of the blocks", Options(("fixed", "random")), "fixed"),
    Setting("blind", "single: the pages never show a partner's kind; double: the console "
            "neither, until export", Options(BLINDS), "single"),
    Setting("questions", "the questions, one `[questions.ID]` table each", default=None,
            allowed=f"up to {MAX_QUESTIONS} tables"),
    Setting("blocks", "the blocks, one `[[blocks]]` table each",
            allowed=f"1 to {MAX_BLOCKS} tables"),
    Setting("analysis", "the hypothesis `study report` tests first, one `[analysis]` table",
            default=None, allowed="a table (its keys below)"),
    Setting("online", "a study served to a recruitment panel: its identifiers and codes, one "
            "`[online]` table", default=None, allowed="a table (its keys below)"),
)  # fmt: skip
"""The keys of the protocol file itself."""

MAX_PANEL_IDS = 8
"""Most panel identifiers a protocol records."""

MAX_PAGE_CHARS = 10_000
"""Longest text of an instructions or consent page (characters)."""

HIDDEN_TAB_RULES = ("record", "refuse")
"""What a hidden tab during a trial does: recorded and the person told, or the person refused."""

PLAY_RULES = ("off", "record", "refuse")
"""What a page below the frame rate and window bounds during a trial does: nothing, recorded and
the person told, or the person refused."""

ONLINE_SETTINGS = (
    Setting("panel_ids", "the join link's query parameters recorded for its participant",
            default=None, allowed=f"up to {MAX_PANEL_IDS} names (letters, digits, _)",
            default_shown="none"),
    Setting("completion_code", "the code the end page shows", default=None,
            allowed="1-64 letters, digits, _ or -"),
    Setting("completion_url", "the link back to the panel the end page shows", default=None,
            allowed="an https link"),
    Setting("refusal_code", "the code shown to a participant screened out", default=None,
            allowed="1-64 letters, digits, _ or -"),
    Setting("refusal_url", "the link back shown to a participant screened out", default=None,
            allowed="an https link"),
    Setting("instructions", "the instructions page, shown before the game", default=None,
            allowed=f"text of at most {MAX_PAGE_CHARS} characters (lines kept)"),
    Setting("instructions_file", "the instructions page's text in a file beside the protocol",
            default=None, allowed="a UTF-8 text file's name"),
    Setting("consent", "the consent page: a participant who does not agree is not played",
            default=None, allowed=f"text of at most {MAX_PAGE_CHARS} characters (lines kept)"),
    Setting("consent_file", "the consent page's text in a file beside the protocol",
            default=None, allowed="a UTF-8 text file's name"),
    Setting("screen_round_trip_p95_ms", "a page whose connect-time round trips' 95th "
            "percentile is above it is refused at entry",
            Interval(float, 1.0, 10_000.0, unit="ms"), None, default_shown="no screening"),
    Setting("screen_frame_rate_hz", "a page drawing fewer animation frames a second than "
            "this over its connect-time exchanges is refused at entry",
            Interval(float, 1.0, 1000.0, unit="Hz"), None, default_shown="no screening"),
    Setting("screen_window_width_px", "a page whose window is narrower than this at entry is "
            "refused", Interval(int, 100, 100_000, unit="px"), None,
            default_shown="no screening"),
    Setting("screen_window_height_px", "a page whose window is lower than this at entry is "
            "refused", Interval(int, 100, 100_000, unit="px"), None,
            default_shown="no screening"),
    Setting("screen_hidden_tab", "a tab hidden during a trial: record: recorded and the "
            "person told; refuse: the person is refused", Options(HIDDEN_TAB_RULES), "record"),
    Setting("screen_during_play", "the entry's bounds held during each trial too, the round "
            "trip over the page's last 50 clock exchanges, frame rate and window over its last "
            "2 s: off; record: recorded and the person told; refuse: the person is refused",
            Options(PLAY_RULES), "off"),
)  # fmt: skip
"""The keys of a protocol's ``[online]`` table (`mirror_avatar.lab.design.online`)."""

ANALYSIS_SETTINGS = (
    Setting("primary", "the primary measure, or measures, of the confirmatory test",
            allowed=f"a measure column of the study table (`{TABLE_COLUMNS[0]}`, "
            f"`{TABLE_COLUMNS[1]}`, ...) or a list of 1 to {MAX_PRIMARY}"),
    Setting("direction", "the tested condition's mean against the reference's",
            Options(DIRECTIONS)),
    Setting("contrast", "the tested condition, then its reference", default=None,
            allowed="two condition names",
            default_shown="the condition other than the reference (two conditions only)"),
    Setting("reference", "the condition every other is compared with", default=None,
            allowed="a condition's name", default_shown="the protocol's first condition"),
    Setting("smallest_effect", "the smallest difference of interest, in the primary "
            "measure's units", Interval(float, 0.0, None)),
    Setting("alpha", "the confirmatory test's significance level",
            Interval(float, 0.0, 0.5, closed="right"), 0.05),
)  # fmt: skip
"""The keys of a protocol's analysis (``[analysis]``): its hypothesis (docs/METHODS.md, 15)."""

QUESTION_SETTINGS = (
    Setting("text", "what the page asks", allowed="text"),
    Setting("kind", "the kind of answer", Options(QUESTION_KINDS)),
    Setting("options", "a choice's options", default=None,
            allowed=f"2 to {MAX_OPTIONS} different texts"),
    Setting("points", "a Likert scale's points (answers 1..points)", Interval(int, 2, 11), 7),
    Setting("anchors", "a Likert scale's two ends", default=None, allowed="two texts"),
    Setting("max_chars", "longest text answer", Interval(int, 1, MAX_ANSWER_CHARS, unit="chars"),
            MAX_ANSWER_CHARS),
)  # fmt: skip
"""The keys of a question (``[questions.ID]``)."""

BLOCK_SETTINGS = (
    Setting("name", "the block's name", default=None, allowed="text",
            default_shown="its place, blocks[N]"),
    Setting("order", "the order of its conditions (latin: a cyclic Latin square across "
            "participants; williams: each condition also right before every other equally "
            "often)", Options(ORDERS), "fixed"),
    Setting("after_block", "questions asked after a participant's last trial of the block",
            default=None, allowed="question ids"),
    Setting("conditions", "its conditions, one `[[blocks.conditions]]` table each",
            allowed=f"1 to {MAX_CONDITIONS} tables"),
)  # fmt: skip
"""The keys of a block (``[[blocks]]``)."""

BLIND_METRICS = Setting(
    "show_metrics",
    "the end screen shows the trial's metrics (who led, how long the players "
    "moved together: they may tell a partner's kind, which the pages hide)",
    Flag(),
    False,
)
"""A condition's ``show_metrics``: off unless asked, a protocol's pages being blind to the partners'
kinds (a plan's is on, `mirror_avatar.lab.design.plan.TRIAL_SETTINGS`)."""

CONDITION_TRIAL_SETTINGS = tuple(
    BLIND_METRICS if setting.key == BLIND_METRICS.key else setting for setting in TRIAL_SETTINGS
)
"""A condition's trial keys: the plan's, ``show_metrics`` off unless asked (`BLIND_METRICS`)."""

CONDITION_SETTINGS = (
    Setting("name", "the condition's name, unique in the protocol", allowed="text"),
    Setting("game", "what the players play", Options(CONDITIONS)),
    Setting("players", "its players, `{ label, kind }` each (a player's keys below)",
            allowed=f"1 to {MAX_PLAYERS} tables"),
    Setting("leaders", "the leading players", default=None, allowed="labels of its players"),
    Setting("graph", "who sees and follows whom, in a group", default="complete",
            allowed="complete, ring, path, star or an adjacency matrix"),
    *CONDITION_TRIAL_SETTINGS,
    Setting("after_trial", "questions asked after each trial", default=None,
            allowed="question ids"),
    Setting("delay", "the partners drawn this late on the people's pages (whole control "
            "periods)", Interval(float, 0.0, MAX_DELAY, unit="s"), 0.0),
    Setting("delay_jitter", "the partners' delay varied from sample to sample around `delay` "
            "(whole control periods, in order): the SD of the jitter",
            Interval(float, 0.0, MAX_JITTER, unit="s"), 0.0),
    Setting("jitter_distribution", "the jitter's distribution, zero-mean (exponential: skewed "
            "to long delays, as a network's queues)", Options(JITTERS), "normal"),
    Setting("partner_view", "how the people's pages draw the partners when their links differ: "
            "as_arrives: as each frame arrives; equalised: each sample held until the same "
            "lag after it was taken (local lag); predicted: extrapolated from the partner's "
            "last samples (dead reckoning)", Options(HANDLINGS), "as_arrives"),
    Setting("view_lag", "equalised: the lag after a sample's time at which every page draws it",
            Interval(float, 0.0, MAX_DELAY, unit="s"), None,
            default_shown="the slowest page's one-way delay (half its round trips' p95)"),
    Setting("view_horizon", "predicted: how far ahead of a partner's last sample it is drawn",
            Interval(float, 0.0, MAX_HORIZON, unit="s"), None,
            default_shown="each page's own one-way delay"),
    Setting("occlude", "when the partners are hidden", default=None,
            allowed=f'[[start, end], ...] s within 0..{MAX_OCCLUSION_END:g}, or "whole"'),
    Setting("perturb", "changes of an avatar mid-trial", default=None,
            allowed="{ at, player, set } tables (Perturbations)"),
)  # fmt: skip
"""The keys of a condition (``[[blocks.conditions]]``)."""

PLAYER_SETTINGS = (
    Setting("label", "the player's label", allowed="1-32 letters, digits, '_' or '-'"),
    Setting("kind", "a person, an avatar, or either (balanced across participants)",
            Options(PLAYER_KINDS)),
    Setting("spec", "an avatar's player SPEC", default=None, allowed="a SPEC"),
    Setting("runs", "where an avatar's player runs: stepped by the server, or in the page of "
            "the dyad's one person (a recording, a tabular or deep cyber player)",
            Options(RUNS), "server"),
    Setting("device", "a person's input device", Options(("pointer",)), "pointer"),
)  # fmt: skip
"""The keys of a player of a condition."""

TABLES = {
    "study": STUDY_SETTINGS,
    "question": QUESTION_SETTINGS,
    "block": BLOCK_SETTINGS,
    "condition": CONDITION_SETTINGS,
    "player": PLAYER_SETTINGS,
    "analysis": ANALYSIS_SETTINGS,
    "online": ONLINE_SETTINGS,
}
"""Every table of a protocol file and its declared keys."""


def keys_of(settings: tuple[Setting, ...]) -> tuple[str, ...]:
    """Return the keys a table declares, in order."""
    return tuple(setting.key for setting in settings)


def by_key(settings: tuple[Setting, ...]) -> dict[str, Setting]:
    """Return a table's declared settings by key."""
    return {setting.key: setting for setting in settings}


STUDY, QUESTION, BLOCK, CONDITION, PLAYER, ANALYSIS, ONLINE = (by_key(t) for t in TABLES.values())
"""Each table's settings by key."""


def key_tables() -> dict[str, str]:
    """Return each table's keys as a Markdown table (`TABLES`; the lab guide shows them)."""
    return {name: settings_table(settings) for name, settings in TABLES.items()}
