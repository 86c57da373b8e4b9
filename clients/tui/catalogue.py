"""Keep the catalogues in step with the code: ``python -m clients.tui.catalogue [LANG…]``.

Finds every ``_("…")`` and ``N_("…")`` in ``clients/tui`` and adds the ones a ``.po`` lacks
(with an empty translation, so ``catalogue --check`` and the tests point at them). A new
language is ``python -m clients.tui.catalogue xx`` followed by translating the file it writes.
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

from clients.tui.i18n import DOMAIN, LOCALE_DIR, available, parse_po

PACKAGE = Path(__file__).parent
MARKERS = {"_", "N_"}


def extract(root: Path = PACKAGE) -> dict[str, list[str]]:
    """``{msgid: ["file:line", …]}`` of every marked string under ``root``."""
    found: dict[str, list[str]] = {}
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id in MARKERS
                and node.args
                and isinstance(node.args[0], ast.Constant)
                and isinstance(node.args[0].value, str)
            ):
                where = f"{path.relative_to(root.parent.parent)}:{node.lineno}"
                found.setdefault(node.args[0].value, []).append(where)
    return found


def po_path(lang: str) -> Path:
    return LOCALE_DIR / lang / "LC_MESSAGES" / f"{DOMAIN}.po"


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def missing(lang: str) -> list[str]:
    """Marked strings that ``lang``'s catalogue does not translate."""
    path = po_path(lang)
    have = parse_po(path.read_text(encoding="utf-8")) if path.exists() else {}
    return [m for m in extract() if m not in have]


def update(lang: str) -> int:
    """Append the missing msgids to ``lang``'s catalogue (created if new); returns how many."""
    path = po_path(lang)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = (
        path.read_text(encoding="utf-8")
        if path.exists()
        else (
            f'msgid ""\nmsgstr ""\n"Language: {lang}\\n"\n'
            '"Content-Type: text/plain; charset=UTF-8\\n"\n'
        )
    )
    present = set(parse_po(text)) | {
        ast.literal_eval(line[6:]) for line in text.splitlines() if line.startswith("msgid ")
    }
    sources = extract()
    new = [m for m in sources if m not in present]
    blocks = [f'\n#: {" ".join(sources[m][:3])}\nmsgid {_quote(m)}\nmsgstr ""\n' for m in new]
    path.write_text(text.rstrip("\n") + "\n" + "".join(blocks), encoding="utf-8")
    return len(new)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m clients.tui.catalogue", description=__doc__)
    parser.add_argument("langs", nargs="*", help="languages to update (default: all)")
    parser.add_argument("--check", action="store_true", help="only list untranslated strings")
    args = parser.parse_args(argv)
    langs = args.langs or [lang for lang in available() if lang != "en"]
    status = 0
    for lang in langs:
        if args.check:
            todo = missing(lang)
            for m in todo:
                print(f"{lang}: untranslated {m!r}")
            status |= bool(todo)
        else:
            print(f"{po_path(lang)}: {update(lang)} new strings to translate")
    return status


if __name__ == "__main__":
    sys.exit(main())
