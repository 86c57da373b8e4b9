"""Translations and remembered settings: pure, nothing mounted."""

from __future__ import annotations

import gettext
import io
from pathlib import Path

import pytest

from clients.tui import catalogue, i18n
from clients.tui.settings import Settings


def test_every_marked_string_is_translated_in_every_language() -> None:
    for lang in i18n.available():
        if lang != i18n.SOURCE_LANGUAGE:
            assert catalogue.missing(lang) == [], f"untranslated in {lang}"


def test_compiled_catalogue_is_what_gettext_reads() -> None:
    po = 'msgid ""\nmsgstr "Content-Type: text/plain; charset=UTF-8\\n"\n\n'
    po += 'msgid "Stop"\nmsgstr "Parar"\n\n#, fuzzy\nmsgid "Go"\nmsgstr "Vai"\n'
    po += 'msgid "two\\nlines"\nmsgstr "duas\\n"\n"linhas"\n'
    t = gettext.GNUTranslations(io.BytesIO(i18n.compile_po(po)))
    assert t.gettext("Stop") == "Parar"
    assert t.gettext("Go") == "Go"  # fuzzy entries are not used
    assert t.gettext("two\nlines") == "duas\nlinhas"


def test_bad_catalogue_line_names_the_line() -> None:
    with pytest.raises(ValueError, match="line 2"):
        i18n.parse_po('msgid "a"\nmsgstr nonsense\n')


def test_switching_language_and_unknown_language() -> None:
    assert i18n.set_language("pt") == "pt"
    assert i18n._("Motors") == "Motores"
    i18n.set_language("en")
    assert i18n._("Motors") == "Motors"
    with pytest.raises(ValueError, match="not available; choose one of en, pt"):
        i18n.set_language("xx")


def test_language_from_the_locale(monkeypatch: pytest.MonkeyPatch) -> None:
    for var in ("LANGUAGE", "LC_ALL", "LC_MESSAGES", "LANG"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("LANG", "pt_PT.UTF-8")
    assert i18n.from_environment() == "pt"
    monkeypatch.setenv("LANGUAGE", "de:en")
    assert i18n.from_environment() == "en"


def test_settings_round_trip_and_a_broken_file(tmp_path: Path) -> None:
    path = tmp_path / "darwin" / "tui.toml"
    assert Settings.load(path) == Settings()
    s = Settings("tcp/10.0.0.5:7447", "op2", 'Zé "the" operator', "pt")
    s.save(path)
    assert Settings.load(path) == s
    path.write_text("[tui\nendpoint = ")
    assert Settings.load(path) == Settings()
