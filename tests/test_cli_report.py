"""``suture plot`` / ``suture report``: the output location is checked before any drawing."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from suture_engine.report import cli_report

GOLDEN = Path(__file__).resolve().parent / "golden" / "steps-snag.mcap"


class _Drawn(Exception):
    """Raised by the patched drawing functions: drawing started."""


@pytest.fixture
def no_drawing(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make any figure drawing fail loudly."""
    from suture_engine.report import figures, html

    def draw(*args: object, **kwargs: object) -> None:
        raise _Drawn

    monkeypatch.setattr(figures, "render_figures", draw)
    monkeypatch.setattr(html, "build_report", draw)


def _plot(out: Path) -> tuple[int, str]:
    err = io.StringIO()
    code = cli_report.plot_command(GOLDEN, out=out, stdout=io.StringIO(), err=err)
    return code, err.getvalue()


def _report(out: Path) -> tuple[int, str]:
    err = io.StringIO()
    code = cli_report.report_command(GOLDEN, out=out, stdout=io.StringIO(), err=err)
    return code, err.getvalue()


@pytest.mark.usefixtures("no_drawing")
def test_plot_refuses_an_unwritable_out_before_drawing(tmp_path: Path) -> None:
    blocker = tmp_path / "f"
    blocker.write_text("x")
    for out in (blocker, blocker / "sub", Path("/proc/suture-figures")):
        code, err = _plot(out)
        assert code == 2, err
        assert str(out) in err
    assert blocker.read_text() == "x"
    assert not Path("/proc/suture-figures").exists()


@pytest.mark.usefixtures("no_drawing")
def test_report_refuses_an_unwritable_out_before_drawing(tmp_path: Path) -> None:
    (tmp_path / "d").mkdir()
    blocker = tmp_path / "f"
    blocker.write_text("x")
    for out in (tmp_path / "d", blocker / "r.html", Path("/proc/r.html")):
        code, err = _report(out)
        assert code == 2, err
        assert str(out) in err
    assert list((tmp_path / "d").iterdir()) == []


@pytest.mark.usefixtures("no_drawing")
def test_a_writable_out_goes_on_to_drawing(tmp_path: Path) -> None:
    with pytest.raises(_Drawn):
        _plot(tmp_path / "new" / "figures")
    with pytest.raises(_Drawn):
        _report(tmp_path / "new" / "r.html")
    assert not (tmp_path / "new").exists()
