"""docs/avr.md's figures against what bench_avr and avr-size print for this build: the ctest
doc_figures (label avr), in each AVR build scripts/test.sh makes.

    python3 doc_figures.py BENCH_AVR ELF DOC SLOW_SHIFT AVR_SIZE

With two rates (SLOW_SHIFT 3, build-avr): the table of "Figures", cell by cell, from bench_avr's
lines at 1 m/s; the whole move's worst; the figures quoted in the prose (the interrupts' cycles
and rates, the TWI's clock stretching, "Open"'s load and the real-time lockstep's, from
`bench_avr --realtime`); the flash against avr-size's text + data. With one rate (SLOW_SHIFT 0,
build-avr0): the one-rate build's tick and load. Prints what differs and exits 1; 0 when every
figure is what the commands print.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path


def grouped(n: int | str) -> str:
    """12440 -> '12 440', as the page writes whole numbers."""
    return f"{int(n):,}".replace(",", " ")


def k(n: int | str) -> str:
    """Bytes in kB (1000 bytes), one decimal: 119722 -> '119.7'."""
    return f"{int(n) / 1000:.1f}"


def section(out: str, title: str) -> str:
    """A phase of the bench's output: from the line that starts with title to a blank line."""
    start = out.index("\n" + title) + 1
    end = out.find("\n\n", start)
    return out[start : end if end >= 0 else len(out)]


def find(text: str, pattern: str) -> tuple[str, ...]:
    m = re.search(pattern, text)
    if not m:
        raise SystemExit(f"doc_figures: {pattern!r} is not in bench_avr's output")
    return m.groups()


def two(t: tuple[str, ...]) -> tuple[str, str]:
    first, second = t
    return first, second


def pair(sec: str, label: str) -> tuple[str, str]:
    """The mean and worst printed on the line after a two-rate label."""
    mean, worst = find(sec, re.escape(label) + r"[^\n]*\n\s+([\d.]+) (?:cycles|%) mean\s+([\d.]+)")
    return mean, worst


def run(*argv: str) -> str:
    p = subprocess.run(argv, capture_output=True, text=True, timeout=600, check=False)
    if p.returncode != 0:
        raise SystemExit(f"doc_figures: {' '.join(argv)} exited {p.returncode}: {p.stderr[-500:]}")
    return p.stdout


def doc_table(doc: str, header: str) -> dict[str, tuple[str, str]]:
    """The rows of the table under header: first cell -> (second, third)."""
    lines = doc.splitlines()
    if header not in lines:
        return {}
    rows = {}
    for line in lines[lines.index(header) + 2 :]:
        if not line.startswith("|"):
            break
        name, mean, worst = (c.strip() for c in line.strip().strip("|").split("|"))
        rows[name] = (mean, worst)
    return rows


def two_rates(out: str, elf_flash: int) -> tuple[str, dict[str, tuple[str, str]]]:
    """The table's header and rows, from the bench's output."""
    tick_hz, slow_hz, shift = find(
        out, r"two rates: the servo at (\d+) Hz .*the slow steps at (\d+) Hz .*slow_shift (\d+)"
    )
    n = str(1 << int(shift))
    flash, ram, stack = find(out, r"flash (\d+) bytes .*; RAM (\d+) bytes static .* \+ (\d+) bytes")
    if int(flash) != elf_flash:
        raise SystemExit(f"doc_figures: bench_avr's flash {flash} is not avr-size's {elf_flash}")
    cruise = section(out, "at 1 m/s")
    (other,) = find(cruise, r"at the other (\d+) ticks")
    spare, spare_word = find(cruise, r"40 % is \d+ cycles: (\d+) (to spare|to go)")
    crude, busiest = find(
        cruise, r"cruder bounds[^\n]*\n\s+([\d.]+) % worst\n\s+([\d.]+) % worst with the busiest"
    )
    isr_mean, isr_busiest = find(
        cruise, r"interrupts in one period, measured\n\s+(\d+) cycles mean\s+(\d+) in the busiest"
    )
    wheel = find(
        cruise, r"encoder, free wheel left \(PCINT2\)\s+\d+ /s\s+(\d+) cycles mean\s+(\d+)"
    )
    motor = find(cruise, r"encoder, motor left \(PCINT0\)\s+\d+ /s\s+(\d+) cycles mean\s+(\d+)")
    timer = find(cruise, r"control timer, around the servo\s+\d+ /s\s+(\d+) cycles mean\s+(\d+)")
    edge = find(cruise, r"waited for its interrupt (\d+) cycles mean, (\d+) at most")
    overruns = find(
        out, r"\(slow_overruns\) (\d+), control periods lost \(avr_tick_overruns\) (\d+)"
    )

    def cycles(label: str) -> tuple[str, str]:
        mean, worst = pair(cruise, label)
        return grouped(mean), grouped(worst)

    def pct(label: str, busiest: str = "") -> tuple[str, str]:
        mean, worst = pair(cruise, label)
        return f"{mean} %", f"{worst} %{busiest}"

    load_mean, load_worst = pair(cruise, "CPU load at")
    header = f"| two rates, {int(tick_hz) / 1000:g} kHz / {slow_hz} Hz, at 1 m/s | mean | worst |"
    rows = {
        "servo tick, the interrupts nested in it excluded [cycles]": cycles("servo tick (TICK"),
        f"... at a slow tick (the snapshot, new wheel factors: one tick in {n})": cycles(
            "at a slow tick"
        ),
        "... at the hand-over (the slow steps' results, `planner_ticks` 3 after the snapshot)": (
            cycles("at the hand-over")
        ),
        f"... at the {other} other ticks of a slow period": cycles("at the other"),
        f"slow steps, one run every {n} ticks, preemptions excluded [cycles]": cycles(
            "slow steps, a run"
        ),
        "interrupts per period, each at its rate and its longest [cycles]": cycles(
            "interrupts per period"
        ),
        "interrupts in one period, measured [cycles]": (
            grouped(isr_mean),
            f"{grouped(isr_busiest)} (the busiest)",
        ),
        f"**CPU load over a slow period**: ({n} servo ticks + {n} periods' interrupts + a run of "
        f"the slow steps) / {n} periods": (
            f"{load_mean} %",
            f"**{load_worst} %** (goal 40 %: {grouped(spare)} cycles {spare_word} in {n} periods)",
        ),
        "the same, cruder: every tick at the servo's worst, every TWI interrupt at the longest of "
        "any bus event": (
            "",
            f"{crude} %; {busiest} % with the busiest period's interrupts in every period",
        ),
        "measured: servo + interrupts in one period": pct("measured: servo", " (the busiest)"),
        f"measured: cycles awake in {n} periods (all the work)": pct(
            "measured: cycles awake", " (the busiest)"
        ),
        "control timer's interrupt around the servo [cycles]": two(timer),
        "encoder interrupt, a free wheel / a motor [cycles per edge]": (
            f"{wheel[0]} / {motor[0]}",
            f"{wheel[1]} / {motor[1]}",
        ),
        "an encoder edge waiting for its interrupt [cycles]": two(edge),
        "overruns: `slow_overruns` (the slow steps not done by their hand-over), "
        "`avr_tick_overruns`": (", ".join(overruns), ""),
        "flash / RAM": (
            f"{k(flash)} kB ({grouped(flash)} B) / {k(ram)} kB (the board in `.noinit`) + "
            f"{k(stack)} kB stack (match play, position fixes, the pose's keeping and the quiet "
            "servo compiled out)",
            "",
        ),
    }
    return header, rows


def two_rates_prose(out: str, realtime: str) -> list[str]:
    """The phrases of the page's prose that quote this build's bench."""
    cruise = section(out, "at 1 m/s")
    rt = section(realtime, "at 1 m/s")
    wheel = find(
        cruise, r"encoder, free wheel left \(PCINT2\)\s+(\d+) /s\s+(\d+) cycles mean\s+(\d+)"
    )
    motor = find(cruise, r"encoder, motor left \(PCINT0\)\s+(\d+) /s\s+(\d+) cycles mean\s+(\d+)")
    (timer,) = find(cruise, r"control timer, around the servo\s+\d+ /s\s+(\d+) cycles mean")
    (twi,) = find(cruise, r"  TWI\s+\d+ /s\s+(\d+) cycles mean")
    _, whole_worst = pair(section(out, "the whole move"), "CPU load at")
    load_mean, load_worst = pair(cruise, "CPU load at")
    (spare,) = find(cruise, r"40 % is \d+ cycles: (\d+) to spare")
    _, awake = pair(cruise, "measured: cycles awake")
    _, rt_awake = pair(rt, "measured: cycles awake")
    _, rt_worst = pair(rt, "CPU load at")
    rt_by, rt_word = find(rt, r"40 % is \d+ cycles: (\d+) (to spare|to go)")
    held = {
        int(ev, 16): int(c)
        for ev, c in re.findall(r"  0x([0-9A-F]{2}) [^\n]*held \d+ times, (\d+) cycles max", out)
    }
    read = held.pop(0xA8)
    if not held or max(held.values()) >= 90:
        raise SystemExit(f"doc_figures: the other bus events hold SCL {held}, not under 90 cycles")
    over = "cycles over" if rt_word == "to go" else "cycles to spare"

    def hundreds(rate: str) -> str:
        return grouped(round(int(rate), -2))

    return [
        f"The interrupt costs {timer} cycles around the servo",
        f"the servo's interrupt's {timer} cycles around it",
        f"an edge costs {wheel[1]} cycles ({wheel[2]} at an overflow) for a free wheel",
        f"{motor[1]} ({motor[2]}) for a motor, Z the only register",
        f"At 1 m/s each free wheel gives {hundreds(wheel[0])} edges a second, each motor "
        f"{hundreds(motor[0])}.",
        f"Over the whole move, the GOTO's first steps included, the worst is {whole_worst} %",
        f"the load over a slow period at 1 m/s is {load_mean} % mean and {load_worst} % worst "
        f"({grouped(spare)} cycles of 128 000 to spare; {awake} % measured in the busiest 8 "
        "periods)",
        f"the busiest 8 periods measure {rt_awake} %, but the worst by part is {rt_worst} % "
        f"({grouped(rt_by)} {over})",
        f"the TWI interrupt in C ({twi} cycles an event on average)",
        f"until the interrupt has put the first reply byte in TWDR, {read} cycles "
        f"({read / 16:.0f} us) past the master's low half-bit at 100 kHz",
        "the other bus events hold it under 90 cycles",
    ]


def one_rate_prose(out: str) -> list[str]:
    cruise = section(out, "at 1 m/s")
    tick = find(cruise, r"control tick, computing\s+(\d+) cycles mean\s+(\d+) worst")
    load = find(cruise, r"CPU load of a period at 1000 Hz\s+([\d.]+) % mean\s+([\d.]+) % worst")
    return [
        f"its tick computes {grouped(tick[0])} cycles mean and {grouped(tick[1])} at worst at "
        f"1 m/s, a load of {load[0]} % mean and {load[1]} % worst"
    ]


def main(argv: list[str]) -> int:
    if len(argv) != 5:
        print(__doc__, file=sys.stderr)
        return 2
    bench, elf, doc_path, shift, avr_size = argv
    doc = Path(doc_path).read_text()
    prose = " ".join(doc.split())
    out = run(bench, elf)
    bad = []
    if int(shift) == 0:
        phrases = one_rate_prose(out)
    else:
        text, data = run(avr_size, "-B", elf).splitlines()[1].split()[:2]
        realtime = run(bench, elf, "--realtime")
        header, want = two_rates(out, int(text) + int(data))
        have = doc_table(doc, header)
        if not have:
            bad.append(f"the table headed {header!r} is not in {doc_path}")
        for name in sorted(want.keys() | have.keys()):
            if want.get(name) != have.get(name):
                bad.append(
                    f"row {name!r}: the page says {have.get(name)}, the bench {want.get(name)}"
                )
        phrases = two_rates_prose(out, realtime)
    bad += [f"not in {doc_path}: {p!r}" for p in phrases if p not in prose]
    for line in bad:
        print(f"doc_figures: {line}")
    print(
        f"doc_figures: {len(bad)} figures of {doc_path} differ from what bench_avr prints"
        if bad
        else f"doc_figures: the figures of {doc_path} are what bench_avr prints"
    )
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
