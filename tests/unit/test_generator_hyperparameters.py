"""The IMS generator's hyper-parameters, declared once: every value a declaration refuses is
refused by the constructor's check and by a model file's reader, naming the hyper-parameter;
the constructor's defaults, the methods' table and the command line follow the declarations."""

from __future__ import annotations

import inspect
from pathlib import Path

import click
import numpy as np
import pytest

from mirror_avatar.cli.generator import fit
from mirror_avatar.common.constraints import ConstraintError, Interval, settings_table
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.motion.hyperparameters import (
    GENERATOR,
    GENERATOR_SETTINGS,
    check_hyperparameters,
)

REFUSALS = [
    pytest.param(setting.key, value, id=f"{setting.key}={value!r}")
    for setting in GENERATOR_SETTINGS
    if setting.constraint is not None
    for value in setting.constraint.refused()
]
"""Every value a declared hyper-parameter refuses."""


def test_every_hyperparameter_declares_what_it_allows():
    assert all(setting.constraint is not None for setting in GENERATOR_SETTINGS)
    assert len(REFUSALS) >= 2 * len(GENERATOR_SETTINGS)


@pytest.mark.parametrize(("key", "value"), REFUSALS)
def test_a_refused_value_is_refused_before_fitting_naming_its_key(key, value):
    with pytest.raises(ConstraintError) as caught:
        IMSGenerator(**{key: value}).fit([])
    assert caught.value.key == key and str(caught.value).startswith(f"{key}: ")
    assert " is not allowed; give " in str(caught.value) and "\n" not in str(caught.value)


@pytest.mark.parametrize(("key", "value"), REFUSALS)
def test_a_refused_value_in_a_model_file_names_the_file_and_its_key(key, value):
    metadata = {"parameters": {"n_symbols": 8, key: value}, "training": {"groups": ["slow"]}}
    with pytest.raises(ConstraintError) as caught:
        IMSGenerator.from_arrays({}, metadata, "model.npz")
    assert caught.value.key == key and caught.value.source == "model.npz"
    assert str(caught.value).startswith(f"model.npz: {key}: ")


@pytest.mark.parametrize(("window", "hop"), [(8, 5), (60, 31), (4, 3)])
def test_a_hop_longer_than_half_the_window_is_refused_naming_the_hop(window, hop):
    with pytest.raises(ConstraintError) as caught:
        IMSGenerator(window=window, hop=hop).fit([])
    assert (caught.value.key, caught.value.value) == ("hop", hop)
    assert caught.value.constraint == Interval(int, 1, window // 2)


def test_allowed_values_are_kept_as_python_numbers():
    given = {"n_symbols": np.int64(8), "window": np.int32(60), "hop": 30, "rate": 100,
             "pseudo_count": np.float32(0.5), "n_init": 2, "random_state": None,
             "emission": "centroid"}  # fmt: skip
    checked = check_hyperparameters(given)
    assert checked == given | {"pseudo_count": 0.5}
    assert [type(v) for v in checked.values()] == [
        int,
        int,
        int,
        float,
        float,
        int,
        type(None),
        str,
    ]
    assert check_hyperparameters({"n_symbols": "auto", "random_state": 2**32 - 1}) == {
        setting.key: setting.default for setting in GENERATOR_SETTINGS
    } | {"random_state": 2**32 - 1}


def test_the_constructor_defaults_to_the_declared_defaults():
    signature = inspect.signature(IMSGenerator).parameters
    assert list(signature) == list(GENERATOR)
    assert {key: p.default for key, p in signature.items()} == {
        key: setting.default for key, setting in GENERATOR.items()
    }


def test_the_methods_table_their_hyperparameters_as_declared():
    methods = (Path(__file__).parents[2] / "docs" / "METHODS.md").read_text(encoding="utf-8")
    table = settings_table(GENERATOR_SETTINGS)
    assert f"<!-- keys: generator -->\n{table}<!-- end keys -->" in methods, "make docs-tables"


@pytest.mark.parametrize(
    ("option", "key"), [("--symbols", "n_symbols"), ("--seed", "random_state")]
)
def test_generator_fit_takes_its_options_ranges_from_the_declarations(option, key):
    (param,) = [p for p in fit.params if option in p.opts]
    assert str(GENERATOR[key].constraint) in (param.help or "")
    for value in GENERATOR[key].constraint.refused():  # type: ignore[union-attr]
        with pytest.raises(click.BadParameter):
            param.type.convert(str(value), param, None)
