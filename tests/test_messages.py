"""Messages: notes and summaries through the "fencesweep" logger (the CLI shows it on stderr, a
library user routes or silences it), progress as a bar on a terminal, a line every LINE_SECONDS
off it, nothing when off; the API's default progress follows whether a person is watching."""
import io
import logging

import pytest

from fencesweep import cli
from fencesweep.study.sweep import progress as PR


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_lines_print_every_line_seconds_and_at_the_end(monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr(PR.sys, "stderr", err)
    clock = Clock()
    bar = PR.Lines(1000, "b2k2", clock=clock)
    for _ in range(9):
        clock.t += PR.LINE_SECONDS / 4
        bar.update(100)
    bar.close()
    lines = err.getvalue().splitlines()
    # updates at 2.5 s steps: a line at 10 s (400 scenes) and at 20 s (800), then the end
    assert lines[0] == "b2k2: 400 of 1,000 scenes (40 %), 10 s, about 15 s left"
    assert lines[1].startswith("b2k2: 800 of 1,000 scenes (80 %), 20 s")
    assert lines[2].startswith("b2k2: 900 of 1,000 scenes (90 %), 22 s") and len(lines) == 3


def test_short_work_prints_no_line(monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr(PR.sys, "stderr", err)
    clock = Clock()
    bar = PR.Lines(10, "x", clock=clock)
    clock.t = PR.LINE_SECONDS / 2
    bar.update(10)
    bar.close()
    assert err.getvalue() == ""


class _Stream(io.StringIO):
    def __init__(self, tty: bool):
        super().__init__()
        self._tty = tty

    def isatty(self):
        return self._tty


@pytest.mark.parametrize("tty, kind", [(False, "Lines"), (True, "tqdm")])
def test_a_bar_on_a_terminal_lines_off_it(monkeypatch, tty, kind):
    monkeypatch.setattr(PR.sys, "stderr", _Stream(tty))
    monkeypatch.delitem(PR.sys.modules, "ipykernel", raising=False)
    bar = PR.bar(5, "x", True)
    bar.close()
    assert type(bar).__name__.startswith(kind)  # tqdm.auto's class: tqdm_asyncio
    assert type(PR.bar(5, "x", False)).__name__ == "_Off"


def test_the_api_default_progress_follows_a_watching_person(monkeypatch):
    monkeypatch.delitem(PR.sys.modules, "ipykernel", raising=False)
    monkeypatch.delattr(PR.sys, "ps1", raising=False)
    monkeypatch.setattr(PR.sys, "stderr", _Stream(False))
    assert PR.wanted(None) is False and PR.wanted(True) is True
    monkeypatch.setattr(PR.sys, "stderr", _Stream(True))
    assert PR.wanted(None) is True and PR.wanted(False) is False


def test_notes_go_to_the_fencesweep_logger(caplog):
    from fencesweep.study import api

    with caplog.at_level(logging.INFO, logger="fencesweep"):
        api._nothing("note: something a user should know")
    assert [(r.name, r.levelname, r.getMessage()) for r in caplog.records] == [
        ("fencesweep.study", "INFO", "note: something a user should know")]


def test_the_cli_shows_the_logger_on_stderr_and_restores_it(capsys):
    log = logging.getLogger("fencesweep")
    before = (log.level, log.propagate, list(log.handlers))
    with cli._messages(quiet=False):
        logging.getLogger("fencesweep.study").info("a note")
    with cli._messages(quiet=True):
        logging.getLogger("fencesweep.study").info("hidden")
        logging.getLogger("fencesweep.study").warning("warning: shown")
    assert capsys.readouterr().err == "a note\nwarning: shown\n"
    assert (log.level, log.propagate, list(log.handlers)) == before


def test_the_compile_notice_is_a_warning_of_the_logger_once(monkeypatch, tmp_path, caplog):
    from fencesweep.kernel import cache

    monkeypatch.setattr(cache, "DIR", tmp_path)
    monkeypatch.setattr(cache, "_warm", set())
    with caplog.at_level(logging.INFO, logger="fencesweep"):
        with cache.compiling("nothing"):
            pass
        with cache.compiling("nothing"):  # compiled now: nothing to say
            pass
    assert [(r.name, r.levelname) for r in caplog.records] == [("fencesweep", "WARNING")]
    assert "compiling the nothing kernels (first run on this machine" in caplog.records[0].getMessage()
