"""Translations: gettext catalogues under ``locale/<lang>/LC_MESSAGES/darwin_tui.po``.

The ``.po`` sources are what the repository holds. A ``.mo`` next to one is used when it is
newer; otherwise the catalogue is compiled in memory at import (and written next to the source
when that folder is writable), so an installed package works without a build step.

Adding a language is adding one ``.po`` file: ``available()`` lists every folder that has one.
Strings are marked with ``_("…")`` and looked up on every call, so switching language at run
time only needs the screen to be composed again.
"""

from __future__ import annotations

import ast
import contextlib
import gettext
import io
import locale
import os
import struct
from pathlib import Path

DOMAIN = "darwin_tui"
LOCALE_DIR = Path(__file__).with_name("locale")
SOURCE_LANGUAGE = "en"

_current: gettext.NullTranslations = gettext.NullTranslations()
_language = SOURCE_LANGUAGE


def available() -> list[str]:
    """Languages this build speaks: English plus every folder with a catalogue."""
    found = {p.parents[1].name for p in LOCALE_DIR.glob(f"*/LC_MESSAGES/{DOMAIN}.po")}
    return [SOURCE_LANGUAGE, *sorted(found - {SOURCE_LANGUAGE})]


def from_environment() -> str:
    """The language the user's locale asks for, if this build has it, else English."""
    candidates = [os.environ.get(v, "") for v in ("LANGUAGE", "LC_ALL", "LC_MESSAGES", "LANG")]
    with contextlib.suppress(ValueError):
        candidates.append(locale.getlocale(locale.LC_MESSAGES)[0] or "")
    langs = available()
    for value in candidates:
        for item in value.split(":"):
            code = item.split(".")[0].split("_")[0].lower()
            if code in langs:
                return code
    return SOURCE_LANGUAGE


def set_language(lang: str) -> str:
    """Switch every later ``_()`` to ``lang``; raises ``ValueError`` for an unknown one."""
    global _current, _language
    lang = lang.lower().split("_")[0]
    if lang not in available():
        raise ValueError(
            f"language {lang!r} is not available; choose one of {', '.join(available())} "
            f"(or add {LOCALE_DIR}/{lang}/LC_MESSAGES/{DOMAIN}.po)"
        )
    _current = gettext.NullTranslations() if lang == SOURCE_LANGUAGE else load(lang)
    _language = lang
    return lang


def language() -> str:
    return _language


def _(message: str) -> str:
    return _current.gettext(message)


def N_(message: str) -> str:
    """Mark a string for extraction without translating it now (class attributes)."""
    return message


def load(lang: str) -> gettext.GNUTranslations:
    folder = LOCALE_DIR / lang / "LC_MESSAGES"
    po, mo = folder / f"{DOMAIN}.po", folder / f"{DOMAIN}.mo"
    if mo.exists() and (not po.exists() or mo.stat().st_mtime >= po.stat().st_mtime):
        with mo.open("rb") as fp:
            return gettext.GNUTranslations(fp)
    data = compile_po(po.read_text(encoding="utf-8"))
    with contextlib.suppress(OSError):
        mo.write_bytes(data)  # a cache only: a read-only install compiles in memory each run
    return gettext.GNUTranslations(io.BytesIO(data))


# ---- a small msgfmt: .po text → .mo bytes (msgid/msgstr/msgctxt, no plurals needed here) ----


def parse_po(text: str) -> dict[str, str]:
    """``{msgid: msgstr}`` of a ``.po`` file; fuzzy and untranslated entries are left out."""
    entries: dict[str, str] = {}
    fields: dict[str, str] = {}
    current: str | None = None
    fuzzy = False

    def flush() -> None:
        nonlocal fuzzy
        if "msgid" in fields and fields.get("msgstr") and not fuzzy:
            key = fields["msgid"]
            if "msgctxt" in fields:
                key = f"{fields['msgctxt']}\x04{key}"
            entries[key] = fields["msgstr"]
        fields.clear()
        fuzzy = False

    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if line.startswith("#,") and "fuzzy" in line:
            flush()
            fuzzy = True
            continue
        if not line or line.startswith("#"):
            continue
        keyword, _sep, rest = line.partition(" ")
        if keyword in ("msgctxt", "msgid", "msgstr"):
            if keyword in ("msgctxt", "msgid") and "msgstr" in fields:
                flush()
            current = keyword
            fields[current] = _po_string(rest, lineno)
        elif line.startswith('"') and current is not None:
            fields[current] += _po_string(line, lineno)
        else:
            raise ValueError(f"line {lineno} of the catalogue is not valid .po syntax: {raw!r}")
    flush()
    return entries


def _po_string(token: str, lineno: int) -> str:
    try:
        value = ast.literal_eval(token)
    except (ValueError, SyntaxError) as exc:
        raise ValueError(f"line {lineno}: bad string {token!r} in the catalogue") from exc
    if not isinstance(value, str):
        raise ValueError(f"line {lineno}: expected a quoted string, got {token!r}")
    return value


def compile_po(text: str) -> bytes:
    """The GNU ``.mo`` bytes of a ``.po`` text (the format ``gettext`` reads)."""
    entries = parse_po(text)
    keys = sorted(entries)
    ids = [k.encode() for k in keys]
    strs = [entries[k].encode() for k in keys]
    n = len(keys)
    header_size = 7 * 4
    id_table = header_size
    str_table = id_table + n * 8
    data_start = str_table + n * 8
    offsets: list[tuple[int, int]] = []
    blob = bytearray()
    for b in ids:
        offsets.append((len(b), data_start + len(blob)))
        blob += b + b"\0"
    str_offsets: list[tuple[int, int]] = []
    for b in strs:
        str_offsets.append((len(b), data_start + len(blob)))
        blob += b + b"\0"
    out = bytearray(struct.pack("<7I", 0x950412DE, 0, n, id_table, str_table, 0, 0))
    for length, offset in offsets + str_offsets:
        out += struct.pack("<2I", length, offset)
    return bytes(out + blob)
