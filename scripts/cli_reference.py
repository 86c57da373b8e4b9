"""Write docs/cli.md: every `darwin` command's `--help`, from the parsers the commands run.

    python scripts/cli_reference.py          # rewrite docs/cli.md
    python scripts/cli_reference.py --check  # exit 1 when docs/cli.md is out of step

tests/unit/test_docs.py runs the check, so the reference never drifts from the programs.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PAGE = REPO / "docs" / "cli.md"
WIDTH = "100"  # argparse wraps at $COLUMNS: fixed, so the page is the same on every terminal

INTRO = """\
# Command reference

Every program is a subcommand of `darwin`; `darwin COMMAND --help` prints the same text as
below. This page is generated from the programs' own parsers by `python scripts/cli_reference.py`
and a test fails when it is out of step, so it cannot drift.

Clients find the robot through `--connect ENDPOINT --robot NAME`, else `DARWIN_ENDPOINT` and
`DARWIN_ROBOT`, else `tcp/127.0.0.1:7447` and `op1`. Every program prints its addresses one per
line as `name: address`, and an expected failure as one line naming the cause and the fix, with
exit status 1.

| command | what it does |
|---|---|
"""


def render() -> str:
    os.environ["COLUMNS"] = WIDTH
    # Defaults under the user's home read as `~/…`, not as this machine's home directory.
    os.environ["XDG_CONFIG_HOME"] = "~/.config"
    sys.path.insert(0, str(REPO))
    from robot_daemon.cli import COMMANDS, command_parser

    parts = [INTRO]
    parts += [f"| [`darwin {name}`](#darwin-{name}) | {text} |\n" for name, (_, text) in
              COMMANDS.items()]
    for name in COMMANDS:
        try:
            _, parser = command_parser(name)
            text = parser.format_help().rstrip()
        except ModuleNotFoundError as exc:  # an extra that is not installed here
            text = f"(needs a package that is not installed: {exc.name})"
        parts.append(f"\n## darwin {name}\n\n```text\n{text}\n```\n")
    return "".join(parts)


def main(argv: list[str]) -> int:
    text = render()
    if "--check" in argv:
        if PAGE.read_text() != text:
            print(f"{PAGE.relative_to(REPO)} is out of step with the programs' --help: "
                  "run `python scripts/cli_reference.py`", file=sys.stderr)
            return 1
        return 0
    PAGE.write_text(text)
    print(f"cli reference: {PAGE.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
