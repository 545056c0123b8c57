"""Benchmark of the STM32 binary in the emulator (harness/stm32): its figures and its goal.

The robot drives 2.4 m straight at 1 m/s (1 m/s^2), as bench_avr drives the AVR binary, while a
master polls CHECK_BUSY every 10 ms and reads POSITION every 20 ms over I2C at 100 kHz. unicorn
counts the instructions the binary executes (a block hook); it has no cycle model, so the CPU load
is estimated from them with a stated cycles-per-instruction assumption.

Printed: instructions per control tick (the SysTick handler), split into the servo and the planner
step (planner.c's board_slow(): orders, profiles, faults, uncertainty, the replies; one rate,
slow_shift 0, it runs inside the tick),
mean and worst over the move and at 1 m/s (true speed at least 0.95 m/s); the I2C interrupts'
instructions per bus event; the estimated CPU load at 180 MHz; flash and RAM from the ELF's
sections. Then the AVR's figures beside, from harness/avr's bench_avr on the one-rate AVR build
when it is built (scripts/test.sh builds it in build-avr0), otherwise the command that prints
them.

The goal (issue 19, docs/stm32.md): the busiest control period at 1 m/s, the tick and the I2C
interrupts up to the next, 5 % of the CPU or less, every feature at the servo rate; marked met or
MISSED, with a summary line last; --strict exits 1 on a miss.

--corners: tours of points queued at once with PASS_THROUGH (APPEND | PASS_THROUGH, the curves
of docs/control.md "Corners"), each on a board of its own (CORNER_TOURS: sharp turns, gentle
ones, short lines): the busiest period is then over the whole of every tour, the curves'
planning and following included, with the same goal; the other figures are the busiest tour's.

    python bench/stm32.py [build-stm32/asserv_stm32.elf] [--fixes | --corners] [--strict]
                          [--avr-bench PATH --avr-elf PATH]
"""

from __future__ import annotations

import argparse
import math
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "harness" / "stm32"))

from board import SYSCLK_HZ, Stm32Board, robot  # noqa: E402
from emu import EmuError  # noqa: E402
from unicorn.arm_const import UC_ARM_REG_LR  # noqa: E402

from asserv import Board, Status  # noqa: E402
from asserv.goals import Goals, add_strict_flag  # noqa: E402
from asserv.sim._core import ffi, lib  # noqa: E402

CPI = 1.5  # cycles per instruction assumed (see CPI_WHY)
CPI_WHY = (
    "Cortex-M4: most instructions 1 cycle, loads and stores 2 (1 when pipelined), taken "
    "branches 2..4, 32-bit divides 2..12; the flash accelerator (ART: prefetch, 1 KiB of "
    "instruction cache) hides the 5 wait states on most fetches. 1.5 is a pessimistic mean."
)
EXCEPTION_CYCLES = 24  # entry 12 + return 12 (Cortex-M4 interrupt latency, no FPU context)
CRUISE_MM_S, CRUISE_END_MM_S = 950.0, 900.0
# --fixes: the ages of the fixes in turn [ms], up to SET_FIX's 500 (a camera's 350 among them).
FIX_AGES_MS = (0, 100, 350, 500, 50, 200)
# --corners: the tours from (-1300, 0) [mm], every point queued with PASS_THROUGH: sharp turns
# on long lines; gentle turns (about 10 degrees), whose curves take the most tries to fit within
# half of each line; short lines (250 mm) with turns of 30 to 40 degrees.
CORNER_TOURS = (
    ((-600, 0), (-100, 500), (400, 0), (700, 400), (1100, 0)),
    ((-900, 0), (-500, 70), (-100, 0), (300, 70), (700, 0), (1100, 70)),
    ((-1050, 0), (-850, 150), (-650, 0), (-450, 150), (-250, 0), (-50, 150), (150, 0)),
)
# The goal (docs/stm32.md): the busiest control period at 1 m/s, every feature on.
GOAL_LOAD_PCT = 5.0


class Stat:
    def __init__(self) -> None:
        self.values: list[int] = []

    def add(self, v: int) -> None:
        self.values.append(v)

    def mean(self) -> float:
        return sum(self.values) / len(self.values) if self.values else 0.0

    def worst(self) -> int:
        return max(self.values, default=0)


class Bench(Stm32Board):
    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        cpu = self.cpu
        # The planner step, planner.c's board_slow() (called from the tick at one rate); without
        # its symbol the split is not measured (printed as such) and the tick still is.
        self.slow_entry = cpu.symbols.get("board_slow", 1) & ~1
        self._slow_at: int | None = None
        self._slow_ret = 0
        self.slow_insns = 0
        self.thread_insns = 0  # the main loop's (thread mode): not the handlers'
        cpu.on_block = self._on_block
        cpu.count_instructions(True)
        self.parts: dict[str, dict[str, Stat]] = {
            p: {k: Stat() for k in ("tick", "servo", "slow")} for p in ("move", "cruise")
        }
        self.i2c_events = Stat()
        self.cruise_ticks: dict[int, int] = {}  # tick number -> its instructions, at 1 m/s
        self.i2c_after: dict[int, int] = {}  # I2C instructions while self.ticks == k
        self.phase = "move"
        self.whole = False  # --corners: every tick of the move counts in the busiest period
        self.truth = ffi.new("struct sim_truth *")
        # The true pose after each tick [mm, mm, degrees]: the fixes of --fixes are measured
        # there, as a lidar's would be.
        self.poses: dict[int, tuple[float, float, float]] = {}

    def _on_block(self, address: int, n: int) -> None:
        cpu = self.cpu
        if not cpu.active:
            self.thread_insns += n
        if address == self.slow_entry:
            self._slow_at = cpu.insns - n
            self._slow_ret = cpu.reg(UC_ARM_REG_LR) & ~1
        elif self._slow_at is not None and address == self._slow_ret:
            self.slow_insns += cpu.insns - n - self._slow_at
            self._slow_at = None

    def control_tick(self) -> None:
        i0, s0, t0 = self.cpu.insns, self.slow_insns, self.thread_insns
        super().control_tick()
        tick = self.cpu.insns - i0 - (self.thread_insns - t0)
        slow = self.slow_insns - s0
        lib.sim_get_truth(self.sim, self.truth)
        p = self.truth.odo_pose
        self.poses[self.ticks] = (p.x_mm, p.y_mm, math.degrees(p.heading_rad))
        v = self.truth.v_mm_s
        if self.phase == "move" and v >= CRUISE_MM_S:
            self.phase = "cruise"
        elif self.phase == "cruise" and v < CRUISE_END_MM_S:
            self.phase = "after"
        if self.phase == "cruise" or self.whole:
            self.cruise_ticks[self.ticks] = tick
        parts = [self.parts["move"]] + ([self.parts["cruise"]] if self.phase == "cruise" else [])
        for p in parts:
            p["tick"].add(tick)
            p["servo"].add(tick - slow)
            p["slow"].add(slow)

    def _timed(self, fn: Any, *args: Any) -> Any:
        i0, t0 = self.cpu.insns, self.thread_insns
        out = fn(*args)
        n = self.cpu.insns - i0 - (self.thread_insns - t0)
        self.i2c_events.add(n)
        self.i2c_after[self.ticks] = self.i2c_after.get(self.ticks, 0) + n
        return out

    def worst_period(self) -> int:
        """The busiest control period at 1 m/s (with --corners, of the whole tour): its tick
        and the I2C interrupts up to the next tick [instructions]."""
        return max(
            (n + self.i2c_after.get(k + 1, 0) for k, n in self.cruise_ticks.items()), default=0
        )

    def ev_start(self, read: bool) -> None:
        self._timed(super().ev_start, read)

    def ev_byte(self, b: int) -> None:
        self._timed(super().ev_byte, b)

    def ev_stop(self) -> None:
        self._timed(super().ev_stop)

    def ev_read_end(self, ack: bool) -> None:
        self._timed(super().ev_read_end, ack)


def flash_figures(elf: str) -> list[str]:
    """The calibration's two logs in flash (firmware/ports/stm32/nvm.c): a record's write after
    SET_ODOMETRIE, and the run-time erases of a switch from a full log to the other, in the
    emulator: the lines to print."""
    lines = []
    slot, slots, start_free = 16, 1024, 64  # stm32_nvm.h
    bc, sc, f = robot()
    b = Stm32Board(elf, sc, f, bc)
    board = Board(b.bus)
    board.set_odometrie(1500, 28037, -700)
    t0 = b.now_ns
    while b.flash.programs < slot // 4 or b.flash.busy():
        b.advance_ns(10_000)
    words = b.flash.programs
    lines.append(
        "\n---- the calibration in flash (sectors 1 and 7, two logs of 16-byte records) ----"
    )
    lines.append(
        f"a record: {words} words of 32 bits, written {(b.now_ns - t0) / 1e6:.1f} ms after "
        f"SET_ODOMETRIE's last byte; each word stalls the CPU's flash fetches "
        f"{b.flash.PROGRAM_NS / 1000:.0f} us (data sheet typical, 100 us at most); worst "
        f"stall of an interrupt in the emulator {max(b.stalls, default=0) / 1000:.1f} us"
    )
    # A full log: the next record waits for no order to run, then the other sector's erase.
    log = bytes(b.flash.data[:slot]) * (slots - start_free)
    switched = b""
    for sector, most, nvm, nvm_b in (
        (7, "2 s", log, None),
        (1, "500 ms", log + bytes(b.flash.data[:slot]) * start_free, "switched"),
    ):
        b = Stm32Board(elf, sc, f, bc, nvm=nvm, nvm_b=switched if nvm_b else None)
        board = Board(b.bus)
        for i in range(start_free + 1):
            board.set_odometrie(i, 28000, 0)
            b.sleep(0.008)
        b.sleep(1.2)
        switched = bytes(b.flash.data_b[:slot]) * (slots - start_free)
        erase = max(b.stalls, default=0)
        lines.append(
            f"a run-time switch to sector {sector} (the log full, no order running, motors "
            f"off): {b.flash.erases} erase of sector {b.flash.erased[0]}, the CPU stalled "
            f"{erase / 1e6:.0f} ms (data sheet typical at x32; {most} at most), "
            f"{b.lost_ticks} control ticks lost, {b.watchdog_resets} watchdog resets (its "
            f"window widened to 5 s for it)"
        )
    b = Stm32Board(elf, sc, f, bc, nvm=log + bytes(slot))
    lines.append(
        f"start-up with fewer than {start_free} free slots: sector {b.flash.erased[0]} erased and "
        f"the record written there before the control starts, the start-up "
        f"{b.boot_stall_ns / 1e6:.0f} ms longer"
    )
    return lines


def sizes(b: Stm32Board) -> tuple[int, int]:
    s = b.cpu.sections
    flash = sum(s.get(n, 0) for n in (".isr_vector", ".text", ".ARM.exidx", ".data"))
    ram = s.get(".data", 0) + s.get(".bss", 0) + s.get(".noinit", 0)
    return flash, ram


def load_pct(insns: float) -> float:
    return (insns * CPI + EXCEPTION_CYCLES) / (SYSCLK_HZ / 1000) * 100


def side_by_side(b: Bench, avr: str) -> None:
    """The figures of both boards at 1 m/s, one line each (the AVR's parsed from bench_avr)."""
    cruise = avr.split("at 1 m/s", 1)[-1]
    tick = re.search(r"control tick, computing\s+(\d+) cycles mean\s+(\d+) worst", cruise)
    load = re.search(
        r"CPU load of a period at\s+\d+ Hz\s+([\d.]+) % mean\s+([\d.]+) % worst", cruise
    )
    mem = re.search(r"flash (\d+) bytes .*?RAM (\d+) bytes", avr)
    if not (tick and load and mem):
        print("\n(bench_avr's output was not recognised: no side-by-side table)")
        return
    t = b.parts["cruise"]["tick"]
    flash, ram = sizes(b)
    est = "cycles (est.)"
    rows = [
        ("control tick at 1 m/s, mean", f"{t.mean() * CPI:.0f} {est}", tick[1] + " cycles"),
        ("control tick at 1 m/s, worst", f"{t.worst() * CPI:.0f} {est}", tick[2] + " cycles"),
        ("CPU load of a period, worst", f"{load_pct(b.worst_period()):.1f} %", load[2] + " %"),
        ("flash [bytes]", str(flash), mem[1]),
        ("RAM, static [bytes]", str(ram), mem[2]),
    ]
    print(f"\n{'one rate, at 1 kHz':<30} {'STM32F446RE, 180 MHz':>24} {'ATmega1284P, 16 MHz':>24}")
    for name, st, av in rows:
        print(f"{name:<30} {st:>24} {av:>24}")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("elf", nargs="?", default=str(ROOT / "build-stm32" / "asserv_stm32.elf"))
    ap.add_argument(
        "--avr-bench", default=str(ROOT / "build-avr0" / "harness" / "avr" / "bench_avr")
    )
    ap.add_argument(
        "--avr-elf",
        default=str(ROOT / "build-avr0" / "harness" / "avr" / "firmware" / "asserv_avr.elf"),
    )
    ap.add_argument(
        "--fixes",
        action="store_true",
        help="a SET_FIX every 100 ms of the move (10 mm, 1 degree, 0 to 500 ms old): the "
        "fusion's cost",
    )
    ap.add_argument(
        "--corners",
        action="store_true",
        help="tours of points queued with PASS_THROUGH: the curves' cost, the busiest period "
        "over the whole of every tour",
    )
    add_strict_flag(ap)
    return ap.parse_args(argv)


@dataclass
class Run:
    """What a run of the bench measured (``measure``), for ``report`` to print and mark."""

    b: Bench
    ticks: int  # at the end of the move
    fix_info: str  # with --fixes: FIX_INFO, read after it (the other figures count its bytes)
    flash: list[str]  # flash_figures()
    avr_cmd: list[str]
    avr: str | OSError | None  # bench_avr's output, its failure to start, or None: not built
    tours: list[tuple[tuple[tuple[int, int], ...], int]]  # --corners: each one's busiest period


def measure(args: argparse.Namespace) -> Run | int:
    """The emulated runs of the bench (the move, the calibration's logs, the AVR's bench_avr
    when built), or the exit code of an error already reported."""
    if args.fixes and args.corners:
        print("bench/stm32.py: --fixes and --corners: one at a time", file=sys.stderr)
        return 2
    if not Path(args.elf).is_file():
        print(
            f"bench/stm32.py: {args.elf}: no such file (build it: docs/stm32.md)", file=sys.stderr
        )
        return 2
    tours: list[tuple[tuple[tuple[int, int], ...], Bench, int, str]] = []
    for tour in CORNER_TOURS if args.corners else ((),):
        try:
            tours.append(drive(args, tour))
        except EmuError as e:
            print(f"bench/stm32.py: {e}", file=sys.stderr)
            return 2
    _, b, ticks, fix_info = max(tours, key=lambda t: t[1].worst_period())
    flash = flash_figures(args.elf)
    avr_bench, avr_elf = Path(args.avr_bench), Path(args.avr_elf)
    cmd = [str(avr_bench), str(avr_elf), "--no-profile"]
    avr: str | OSError | None = None
    if avr_bench.is_file() and avr_elf.is_file():
        try:
            avr = subprocess.run(cmd, check=False, capture_output=True, text=True).stdout
        except OSError as e:
            avr = e
    return Run(
        b, ticks, fix_info, flash, cmd, avr, [(t, tb.worst_period()) for t, tb, _, _ in tours]
    )


def drive(
    args: argparse.Namespace, tour: tuple[tuple[int, int], ...]
) -> tuple[tuple[tuple[int, int], ...], Bench, int, str]:
    """One emulated board driven from (-1300, 0): 2.4 m straight to (1100, 0), or through
    ``tour`` (--corners). Returns the tour, the board, its ticks and FIX_INFO (--fixes)."""
    # The robot at (-1300, 0), heading 0, and the board told so.
    bc, sc, f = robot({"start": (-1300.0, 0.0, 0.0)})
    b = Bench(args.elf, sc, f, bc)
    board = Board(b.bus)
    board.set_vitesse_traj(100, 100)
    if tour:
        b.whole = True
        for px, py in tour:
            board.goto(px, py, append=True, through=True)
    else:
        board.goto(1100, 0)
    polls = 0
    while b.now_ns < (30 if args.corners else 10) * 1_000_000_000:
        b.sleep(0.01)
        polls += 1
        if not board.check_busy() & Status.BUSY_TRAJET:
            break
        if polls % 2 == 0:
            board.position()
        if args.fixes and polls % 10 == 0:
            # The true pose FIX_AGES_MS[k] ago, 5 mm and 0.5 degree off: each fix is fused at
            # its time and its correction carried to now (1 tick = 1 ms).
            age = FIX_AGES_MS[(polls // 10) % len(FIX_AGES_MS)]
            x, y, h = b.poses.get(b.ticks - age) or b.poses[max(b.poses)]
            board.fix(x + 5, y - 5, h + 0.5, 10, 1.0, age)
    return tour, b, b.ticks, str(board.fix_info()) if args.fixes else ""


def report(run: Run, args: argparse.Namespace) -> int:
    """Prints the figures of ``run`` and its goal marked; the exit code."""
    b, ticks = run.b, run.ticks
    flash, ram = sizes(b)
    print(
        f"asserv_stm32.elf on an STM32F446RE at {SYSCLK_HZ // 1_000_000} MHz (unicorn): control "
        "at 1000 Hz, one rate (slow_shift 0), motor encoders 2048 counts/turn in hardware"
    )
    print(
        f"flash {flash} bytes (vectors + .text + .data); "
        f"RAM {ram} bytes static (.data + .bss + .noinit)"
    )
    if args.corners:
        for tour, n in run.tours:
            points = " ".join(f"({x}, {y})" for x, y in tour)
            print(
                f"a tour through {points} (PASS_THROUGH): busiest period {n} instructions, "
                f"{load_pct(n):.2f} %"
            )
        print(f"the busiest tour's figures: {ticks} ticks ({ticks / 1000:.2f} s)")
    else:
        print(f"{ticks} ticks ({ticks / 1000:.2f} s), 2.4 m at 1 m/s, 1 m/s^2")
    if args.fixes:
        print(f"with a SET_FIX every 100 ms: {run.fix_info}")
    if "board_slow" not in b.cpu.symbols:
        print("(no board_slow symbol in this ELF: the servo / planner split is not measured)")
    for part, title in (("move", "over the move"), ("cruise", "at 1 m/s")):
        p = b.parts[part]
        print(f"\n{title} ({len(p['tick'].values)} ticks): instructions per tick")
        for k, name in (
            ("tick", "control tick (SysTick handler)"),
            ("servo", "  servo (the tick without the planner step)"),
            ("slow", "  planner (board_slow: orders, profiles, faults)"),
        ):
            s = p[k]
            print(f"  {name:<50} {s.mean():8.0f} mean {s.worst():8d} worst")
        t = p["tick"]
        print(
            f"  CPU load at {SYSCLK_HZ // 1_000_000} MHz, 1 kHz, {CPI} cycles/instruction "
            f"+ {EXCEPTION_CYCLES} cycles of exception entry and return: "
            f"{load_pct(t.mean()):.2f} % mean, {load_pct(t.worst()):.2f} % worst"
        )
    busiest = load_pct(b.worst_period())
    where = "of the tours" if args.corners else "at 1 m/s"
    print(
        f"  busiest period {where}, the tick and the I2C interrupts up to the next: "
        f"{b.worst_period()} instructions, {busiest:.2f} %"
    )
    what = "with a position fix every 100 ms" if args.fixes else "without position fixes"
    if args.corners:
        what = "through PASS_THROUGH corners"
    goals = Goals("bench/stm32.py")
    goals.check(f"goal: the busiest period {where}, {what}", busiest, "<=", GOAL_LOAD_PCT, "%")
    for line in goals.lines():
        print(line)
    ev = b.i2c_events
    print(
        f"\nI2C interrupts: {len(ev.values)} bus events, {ev.mean():.0f} instructions mean, "
        f"{ev.worst()} worst per event"
    )
    print(f"cycles per instruction assumed: {CPI}: {CPI_WHY}")
    for line in run.flash:
        print(line)
    print("\n---- the AVR beside: ATmega1284P at 16 MHz, one rate (harness/avr/bench_avr) ----")
    if isinstance(run.avr, OSError):
        print(f"bench/stm32.py: {run.avr_cmd[0]}: {run.avr}", file=sys.stderr)
        return 1
    if run.avr is not None:
        print(run.avr, end="")
        side_by_side(b, run.avr)
    else:
        print(
            "not built here; build it and print its figures with:\n"
            "  cmake -S . -B build-avr0 -G Ninja -DASSERV_AVR_HARNESS=ON -DASSERV_TESTS=OFF "
            "-DASSERV_AVR_SLOW_SHIFT=0 && cmake --build build-avr0\n  " + " ".join(run.avr_cmd)
        )
    print(f"\n{goals.summary()}")
    return goals.exit_code(args.strict)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    run = measure(args)
    if isinstance(run, int):
        return run
    return report(run, args)


if __name__ == "__main__":
    sys.exit(main())
