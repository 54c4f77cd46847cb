"""Calling the ``ratectl`` command in-process, for the CLI tests."""

import contextlib
import io
import re

from ratectl.cli import main as cli


def run(argv):
    """(exit code, stdout, stderr) of ``ratectl argv``; argparse exits become codes."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = cli.main(argv)
        except SystemExit as exc:
            code = exc.code
    return code, out.getvalue(), err.getvalue()


def numbers(line):
    """The decimal numbers in a line of output."""
    return [float(x) for x in re.findall(r"[-+]?\d+\.\d*(?:e[-+]?\d+)?", line)]
