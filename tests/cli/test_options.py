"""The command line's reading of option texts into the jobs' arguments, and the way back."""

from __future__ import annotations

import pytest

from aeromag_env.cli.options import option_for, parse_lines, parse_seeds, parse_segment
from aeromag_env.cli.parser import build_parser
from aeromag_env.errors import AeromagError, ArgumentError


def test_line_and_segment_texts_become_the_jobs_arguments() -> None:
    assert parse_lines("1001, 1003") == (1001.0, 1003.0)
    assert parse_segment("100:400.5") == (100.0, 400.5)
    assert parse_seeds("0-2,7") == (0, 1, 2, 7)


@pytest.mark.parametrize(
    ("parse", "text", "message"),
    [
        (parse_lines, "a,b", "lines needs line ids"),
        (parse_lines, "", "lines needs finite"),
        (parse_lines, "nan", "lines needs finite"),
        (parse_segment, "5", "segment_s needs T0:T1"),
        (parse_segment, "9:3", "finite T0 < T1"),
        (parse_segment, "0:inf", "finite T0 < T1"),
    ],
)
def test_bad_option_values_are_one_line_errors(parse, text: str, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(AeromagError, match=message):
        parse(text)


def test_an_argument_error_is_said_with_the_commands_option() -> None:
    sub = build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    assert option_for(sub["compensate"], "r_std_nt") == "--r-std-nt"
    assert option_for(sub["compensate"], "calibration_window_s") == "--calibration-window"
    assert option_for(sub["info"], "lines") == "--line"
    assert option_for(sub["info"], "alpha") == "alpha"  # no such option: the library's name
    error = ArgumentError("r_std_nt", "must be > 0", 0.0)
    assert str(error) == "r_std_nt must be > 0, got 0"
    assert error.spelled("--r-std-nt") == "--r-std-nt must be > 0, got 0"
