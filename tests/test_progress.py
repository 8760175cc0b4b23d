"""The progress of long runs (legsim.progress): on a terminal a bar reaching 100 %, with an
estimate of the time left and a line whose width does not change as the numbers do; elsewhere
(a log file, a pipe) a plain line every LINE_INTERVAL seconds."""

import io
import re

from legsim.progress import LINE_INTERVAL, ProgressBar, ProgressLines, progress_for

ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


class Terminal(io.StringIO):
    def isatty(self):
        return True


def frames(stream: io.StringIO) -> list[str]:
    """The lines the bar drew, in order, without colours and cursor movements."""
    text = stream.getvalue()
    return [line for line in (ANSI.sub("", part).rstrip("\n") for part in re.split(r"\r", text)) if line.strip()]


def test_a_bar_only_on_a_terminal_and_lines_elsewhere():
    assert isinstance(progress_for(io.StringIO()), ProgressLines)
    assert progress_for(Terminal(), enabled=False) is None
    assert isinstance(progress_for(Terminal(), label="ball"), ProgressBar)


def test_the_bar_reaches_100_percent_and_is_erased():
    stream = Terminal()
    bar = ProgressBar(stream, label="ball", width=100)
    assert stream.getvalue() == ""  # nothing before the first report: short runs draw nothing
    for t in (1.0, 2.5, 4.0):
        bar(t, 0.0, 4.0)
    drawn = frames(stream)
    percents = [int(re.search(r"(\d+)%", line).group(1)) for line in drawn]
    assert percents[:3] == [25, 62, 100]
    assert drawn[2].startswith("ball ") and "t = 4" in drawn[2] and "/ 4 s" in drawn[2]
    bar.close()
    # Erased: the last thing written moves up to the bar's line and clears it.
    assert stream.getvalue().endswith("\x1b[1A\x1b[2K")


def test_the_estimate_of_the_time_left_follows_the_rate():
    now = [0.0]
    stream = Terminal()
    bar = ProgressBar(stream, label="walk", width=100, clock=lambda: now[0])
    for wall, t in ((0.0, 0.0), (10.0, 1.0), (20.0, 2.0)):
        now[0] = wall
        bar(t, 0.0, 4.0)
    # Half the simulated time in 20 s of wall time: 20 s left.
    assert frames(stream)[-1].endswith("0:00:20 ETA 0:00:20")
    bar.close()


def test_the_line_keeps_its_width_as_the_numbers_change():
    stream = Terminal()
    bar = ProgressBar(stream, label="pronk", width=120)
    for t in (1.234567e-5, 0.5, 3.0, 12.75, 99.5, 100.0):
        bar(t, 0.0, 100.0)
    bar.close()
    drawn = frames(stream)
    assert len({len(line.rstrip()) for line in drawn}) == 1, drawn
    assert max(len(line) for line in drawn) <= 120


def test_a_new_label_starts_a_new_phase():
    now = [0.0]
    stream = Terminal()
    bar = ProgressBar(stream, label="level 0", width=100, clock=lambda: now[0])
    for wall, t in ((0.0, 0.0), (30.0, 4.0)):
        now[0] = wall
        bar(t, 0.0, 4.0)
    now[0] = 40.0
    bar.label = "level 1"
    now[0] = 45.0
    bar(0.0, 0.0, 4.0)
    assert bar.label == "level 1"
    last = frames(stream)[-1]
    assert last.startswith("level 1 ") and " 0% " in last and "0:00:05 ETA" in last  # elapsed restarts
    bar.close()


def test_counting_counts_to_the_total_off_a_terminal_silently():
    from legsim.progress import counting

    quiet = io.StringIO()
    with counting(5, "stress", stream=quiet) as advance:
        advance(1)
    assert quiet.getvalue() == ""
    now = [0.0]
    stream = Terminal()
    with counting(4, "stress", stream=stream, clock=lambda: now[0]) as advance:
        for wall in (10.0, 20.0, 30.0, 40.0):
            now[0] = wall
            advance(1)
    # The last drawing (made as the bar closes): all four done after 40 s of wall time.
    last = frames(stream)[-1]
    assert last.startswith("stress ") and " 4/4 0:00:40 ETA" in last
    assert stream.getvalue().endswith("\x1b[2K")  # erased


def test_counting_starts_from_the_items_already_done():
    # A resumed sweep: 3 of 5 done before, 2 run now.
    stream = Terminal()
    with counting_bar(5, done=3, stream=stream) as advance:
        advance(2)
    assert " 5/5 " in frames(stream)[-1]


def counting_bar(total, **kwargs):
    from legsim.progress import counting

    return counting(total, "sweep", **kwargs)


def test_lines_come_every_interval_in_plain_text_and_a_short_run_writes_none():
    stream, now = io.StringIO(), [100.0]
    lines = ProgressLines(stream, label="pronk", clock=lambda: now[0])
    for k in range(1, 200):  # a report every 0.25 s of wall time, the run from t = 0 to 2 s
        now[0] = 100.0 + 0.25 * k
        lines(0.01 * k, 0.0, 2.0)
    written = stream.getvalue().splitlines()
    # 49.75 s of wall time: one line at 30 s (k = 120, t = 1.2 s of 2), none before.
    assert written == ["pronk: t = 1.2 / 2 s (60%), 0:00:30 elapsed"]
    assert not ANSI.search(stream.getvalue()) and "\r" not in stream.getvalue()
    # The same label keeps the clock (the next line 30 s after the last, at 130 s); a new one
    # (certify's next refinement level) starts it again.
    lines.label = "pronk"
    now[0] = 130.0 + LINE_INTERVAL - 1.0
    lines(1.5, 0.0, 2.0)
    now[0] = 130.0 + LINE_INTERVAL
    lines(1.6, 0.0, 2.0)
    assert stream.getvalue().splitlines()[1:] == ["pronk: t = 1.6 / 2 s (80%), 0:01:00 elapsed"]
    lines.label = "pronk level 1"
    now[0] += LINE_INTERVAL - 1.0
    lines(1.9, 0.0, 2.0)
    now[0] += 1.0
    lines(1.95, 0.0, 2.0)
    assert stream.getvalue().splitlines()[2:] == ["pronk level 1: t = 1.95 / 2 s (98%), 0:00:30 elapsed"]
    short = io.StringIO()
    quick = ProgressLines(short, label="ball", clock=lambda: now[0])
    quick(1.0, 0.0, 2.0)
    assert short.getvalue() == ""
