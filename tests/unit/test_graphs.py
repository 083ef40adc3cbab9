"""Tests of coupling graphs: named topologies, random connected graphs, files, validation."""

import json

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.sessions.graphs import (
    check_graph,
    complete_graph,
    draw_graph,
    graph_source,
    is_connected,
    make_graph,
    neighbours,
    path_graph,
    random_connected_graph,
    read_graph,
    ring_graph,
    star_graph,
)


def test_named_topologies() -> None:
    np.testing.assert_array_equal(complete_graph(3), [[0, 1, 1], [1, 0, 1], [1, 1, 0]])
    np.testing.assert_array_equal(path_graph(3), [[0, 1, 0], [1, 0, 1], [0, 1, 0]])
    assert ring_graph(5).sum(axis=1).tolist() == [2] * 5
    np.testing.assert_array_equal(ring_graph(2), complete_graph(2))
    star = star_graph(4, centre=1)
    assert star.sum(axis=1).tolist() == [1, 3, 1, 1] and neighbours(star, 0).tolist() == [1]
    assert complete_graph(1).tolist() == [[0]] and is_connected(complete_graph(1))
    for name in ("complete", "path", "ring", "star"):
        graph = make_graph(name, 6)
        assert np.array_equal(graph, graph.T) and is_connected(graph)


def test_random_graphs_are_connected_symmetric_and_seeded() -> None:
    graphs = [random_connected_graph(6, np.random.default_rng(s)) for s in range(50)]
    assert all(
        is_connected(g) and np.array_equal(g, g.T) and not g.diagonal().any() for g in graphs
    )
    assert len({g.tobytes() for g in graphs}) > 20
    density = np.mean([g.sum() / 30 for g in graphs])
    assert 0.5 < density < 0.8  # p = 0.5, conditioned on being connected
    again = random_connected_graph(6, np.random.default_rng(7))
    np.testing.assert_array_equal(again, graphs[7])
    np.testing.assert_array_equal(draw_graph(random_connected_graph, 6, 7), graphs[7])


def test_disconnected_graphs() -> None:
    two_pairs = np.kron(np.eye(2, dtype=int), [[0, 1], [1, 0]])
    assert not is_connected(two_pairs)
    with pytest.raises(InputError, match="not connected"):
        check_graph(two_pairs)
    assert check_graph(two_pairs, connected=False).dtype == np.int8
    directed = np.array([[0, 1], [0, 0]])
    assert is_connected(directed)


@pytest.mark.parametrize(
    ("matrix", "problem"),
    [
        (np.ones((2, 3)), "square"),
        (np.full((2, 2), 2) - 2 * np.eye(2), "0 or 1"),
        (np.ones((2, 2)), "diagonal"),
        ([["a", "b"], ["c", "d"]], "numeric"),
    ],
)
def test_bad_matrices_are_refused(matrix, problem) -> None:
    with pytest.raises(InputError, match=problem):
        check_graph(matrix)


def test_bad_topologies() -> None:
    with pytest.raises(InputError, match="unknown topology"):
        make_graph("lattice", 4)
    with pytest.raises(InputError, match="positive integer"):
        complete_graph(0)
    with pytest.raises(InputError, match="centre"):
        star_graph(3, centre=5)
    with pytest.raises(InputError, match="players"):
        check_graph(complete_graph(3), n_players=4)


def test_graph_files(tmp_path) -> None:
    ring = ring_graph(4)
    (tmp_path / "ring.csv").write_text("\n".join(",".join(map(str, row)) for row in ring) + "\n")
    (tmp_path / "ring.json").write_text(json.dumps({"adjacency": ring.tolist()}))
    (tmp_path / "rows.json").write_text(json.dumps(ring.tolist()))
    for name in ("ring.csv", "ring.json", "rows.json"):
        np.testing.assert_array_equal(read_graph(tmp_path / name), ring)
        np.testing.assert_array_equal(graph_source(str(tmp_path / name), 4), ring)
    np.testing.assert_array_equal(graph_source("star", 3), star_graph(3))
    assert graph_source("random", 5) is random_connected_graph


@pytest.mark.parametrize(
    ("name", "text", "problem"),
    [
        ("g.csv", "0,1\n1,0\n", "2 rows for 4 players"),
        ("g.csv", "0,1,0,0\n1,0,0,0\n0,0,0,1\n0,0,1,0\n", "not connected"),
        ("g.csv", "0,x\n1,0\n", "numeric"),
        ("g.json", "{not json", "not valid JSON"),
        ("g.txt", "0", "must be .csv or .json"),
        ("missing.csv", None, "no such file"),
    ],
)
def test_bad_graph_files_name_the_file(tmp_path, name, text, problem) -> None:
    path = tmp_path / name
    if text is not None:
        path.write_text(text)
    with pytest.raises(InputError, match=problem) as error:
        graph_source(str(path), 4)
    assert str(error.value).startswith(str(path))
    with pytest.raises(InputError, match="not a topology"):
        graph_source("lattice", 4)
