"""The one line of a refused command, shared by the bad-input tests: exit status 2, one line of at most the
guard's length, no traceback (warning lines, which a command may print before it refuses, set apart)."""

from hcmt.cli import GUARD, main as cli


def refused(capsys, argv: list[str]) -> str:
    """Run ``hcmt ARGV`` in this process and return the refusal's one line."""
    rc = cli(argv)
    err = [line for line in capsys.readouterr().err.strip().splitlines() if ": warning: " not in line]
    assert rc == 2 and len(err) == 1 and "Traceback" not in err[0], (rc, err)
    assert len(err[0]) <= GUARD, len(err[0])
    return err[0]
