"""``mta field ...`` run in this process for the field tests: its exit code and what it printed,
and what a refusal must look like (exit 2, one line on stderr holding the expected texts, no
traceback)."""
from __future__ import annotations

from mta_sim_ros.cli import main


def field_command(capsys, *args) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``mta field ARGS``."""
    try:
        code = main(["field", *map(str, args)])
    except SystemExit as stop:  # argparse refusing an argument
        code = stop.code
    out = capsys.readouterr()
    return code, out.out, out.err


def field_refused(capsys, expected: tuple, *args) -> str:
    """``mta field ARGS`` refused in one line holding every ``expected`` text; returns the line."""
    code, _, err = field_command(capsys, *args)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert "Traceback" not in err
    for text in expected:
        assert text in lines[0], (text, lines[0])
    return lines[0]
