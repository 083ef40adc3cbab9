"""``mirror-avatar lab preview``: each participant's order and partner kinds, the balance tables
and a one-line verdict, before anyone comes."""

from __future__ import annotations

from pathlib import Path

from mirror_avatar.cli import main
from mirror_avatar.lab.design.protocol import load_protocol

EXAMPLE = Path(__file__).parents[2] / "examples" / "protocol.toml"
THREE = """
seed = 5

[[blocks]]
name = "b"
order = "latin"
""" + "".join(
    f"""
[[blocks.conditions]]
name = "c{c}"
game = "joint"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "P2", kind = "person-or-avatar", spec = "bundled:slow" }},
]
"""
    for c in range(3)
)


def test_the_example_protocol_is_balanced_over_eight_participants(capsys):
    assert main(["lab", "preview", "--protocol", str(EXAMPLE), "--participants", "8"]) == 0
    lines = capsys.readouterr().out.splitlines()
    protocol = load_protocol(EXAMPLE)
    for p in range(8):
        steps = [s for s in protocol.schedule(p) if s.block == 1]
        words = [
            f"{s.name} (P2 {'person' if s.persons['P2'] else 'avatar'})" if s.persons else s.name
            for s in steps
        ]
        assert f"p{p:03d}  alone: solo | partners: {', '.join(words)}" in lines
    table = lines.index("block 'partners' (williams, 4 condition(s)): times at each position")
    assert lines[table + 1].split() == ["position", "1", "2", "3", "4"]
    rows = {" ".join(line.split()[:-4]): line.split()[-4:] for line in lines[table + 2 : table + 8]}
    assert rows == {
        name: ["2"] * 4
        for name in ("follow", "joint", "ring", "lead", "partner person", "partner avatar")
    }
    assert lines[-1].startswith("balanced: every condition at every position equally often")


def test_an_unbalanced_count_is_said_with_the_count_that_balances(tmp_path, capsys):
    path = tmp_path / "three.toml"
    path.write_text(THREE)
    assert main(["lab", "preview", "--protocol", str(path), "--participants", "8"]) == 0
    verdict = capsys.readouterr().out.splitlines()[-1]
    assert verdict.startswith(
        "not balanced: block 'b': conditions not equally often at every position"
    )
    assert verdict.endswith("(12 participants balance every block)")
    assert main(["lab", "preview", "--protocol", str(path), "--participants", "12"]) == 0
    assert capsys.readouterr().out.splitlines()[-1].startswith("balanced:")


def test_an_order_that_is_not_counterbalanced_is_named_with_the_fix(tmp_path, capsys):
    path = tmp_path / "random.toml"
    path.write_text(THREE.replace('order = "latin"', 'order = "random"'))
    assert main(["lab", "preview", "--protocol", str(path), "--participants", "6"]) == 0
    verdict = capsys.readouterr().out.splitlines()[-1]
    assert verdict.startswith("not balanced: block 'b': ")
    assert verdict.endswith(
        '(block \'b\' is not counterbalanced: order = "latin" or "williams" balances it)'
    )


def test_bad_options_are_refused_in_one_line(tmp_path, capsys):
    missing = tmp_path / "none.toml"
    assert main(["lab", "preview", "--protocol", str(missing)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(missing) in err[0]
    assert main(["lab", "preview", "--protocol", str(EXAMPLE), "--participants", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "--participants" in err[-1]


def test_a_protocol_nested_by_dotted_keys_is_refused_in_one_line(tmp_path, capsys):
    path = tmp_path / "dotted.toml"
    dotted = "{" + ".".join(["k"] * 2000) + " = 1}"
    path.write_text(EXAMPLE.read_text().replace('label = "P1"', f"label = {dotted}", 1))
    assert main(["lab", "preview", "--protocol", str(path)]) == 2
    error = capsys.readouterr().err.strip()
    assert (
        error == f"mirror-avatar: error: {path}: is TOML nested deeper than the limit of 32 levels"
    )


def test_control_characters_in_the_protocols_name_are_printed_escaped(tmp_path, capsys):
    path = tmp_path / "\x1b[31mred\x07.toml"
    path.write_text(EXAMPLE.read_text())
    assert main(["lab", "preview", "--protocol", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"protocol {tmp_path}/\\x1b[31mred\\x07.toml: ")
    assert "\x1b" not in out and "\x07" not in out
    assert main(["lab", "preview", "--protocol", str(tmp_path / "\x1b[2Jgone.toml")]) == 2
    assert capsys.readouterr().err.strip().endswith("\\x1b[2Jgone.toml: no such file")
