"""Benchmark of the firmware update over I2C (docs/update.md; prints, asserts nothing).

Today's application image is sent to the bootloader's binary over the emulated bus
(harness/stm32/boot.py) by asserv.update, at 100 kHz and 400 kHz (9 bits a byte, the lockstep's
byte time): version 2 into slot B while slot A runs version 1, then version 3 back into slot A
(each slot runs its own link of the same code: nothing is copied). The flash's erase and program
times are the data sheet's typical ones, as the emulator models them. Printed for each rate:

- for each slot, the download (BEGIN to the header written) and the whole update (BOOTLOADER
  sent to the new application answering), against the bus's limit: the frames a download cannot
  do without (address, designation, offset, the image in 64-byte chunks, PEC; BEGIN and END), 9
  bits a byte. Goal (issue 29): 1.5x the limit or less, each marked met or MISSED
  (asserv.goals), the last line sums them up, --strict exits 1 on a miss; where the rest goes:
  the slot's erase at BEGIN (slot B 1 s, slot A 1.05 s) past what the bootloader holds in RAM
  meanwhile (24 KiB), START's reset (the emulator runs the code in no simulated time: the
  start-up's estimate below, from reset to the first control tick, is added);
- then the bootloader's flash, and the time from reset to the application's first control tick
  (instructions counted by unicorn, at 1.5 cycles each: the bootloader at the HSI's 16 MHz, the
  application's start-up at 16 MHz until its clock set-up, then 180 MHz; plus SysTick's first
  period).

    python bench/update_stm32.py [build-stm32] [--strict]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "harness" / "stm32"))

from board import robot  # noqa: E402
from boot import BootBoard, elf_of_slot_b, with_version  # noqa: E402
from elftools.elf.elffile import ELFFile  # noqa: E402
from emu import SRAM_BASE  # noqa: E402

from asserv import Board  # noqa: E402
from asserv.goals import Goals, add_strict_flag  # noqa: E402
from asserv.update import CHUNK, Updater, load_image  # noqa: E402

CPI = 1.5  # cycles per instruction, as bench/stm32.py
GOAL = 1.5


def bus_limit_s(image_len: int, rate_hz: int) -> float:
    """The frames a download needs at the least, 9 bits a byte: BEGIN (address, 15 bytes, PEC),
    each DATA (address, designation, offset, up to 64 bytes, PEC), END (address, designation,
    PEC)."""
    chunks = -(-image_len // CHUNK)
    nbytes = (1 + 15 + 1) + chunks * (1 + 1 + 4 + 1) + image_len + (1 + 1 + 1)
    return nbytes * 9 / rate_hz


def update_at(elf: Path, boot_elf: Path, rate_hz: int) -> list[tuple[float, float, float, int]]:
    """For the update into slot B, then the one back into slot A: (download [s], START to the
    new application answering [s], whole update [s], image bytes) over the emulated bus."""
    bc, sc, f = robot()
    b = BootBoard(elf, boot_elf, sc, f, bc, byte_ns=9 * 1_000_000_000 // rate_hz)
    out = []
    for version, path in ((2, elf_of_slot_b(elf)), (3, elf)):
        new = with_version(load_image(path), version)
        t0 = b.now_ns
        Board(b.bus).bootloader()
        u = Updater(b.bus)
        b.sleep(0.01)
        assert u.info().dl_slot == new.slot
        t1 = b.now_ns
        u.update(new)
        t2 = b.now_ns
        u.start()
        while b.in_boot():
            b.sleep(0.001)
        assert b.running_version() == version and b.running_slot() == new.slot
        Board(b.bus).check_busy()  # the new application answering
        out.append(
            ((t2 - t1) * 1e-9, (b.now_ns - t2) * 1e-9, (b.now_ns - t0) * 1e-9, len(new.data))
        )
        b.sleep(0.05)
    return out


def flash_bytes(path: Path) -> int:
    with path.open("rb") as fh:
        return sum(
            int(s["p_filesz"])
            for s in ELFFile(fh).iter_segments()
            if s["p_type"] == "PT_LOAD" and s["p_paddr"] < SRAM_BASE
        )


def reset_to_tick(elf: Path, boot_elf: Path) -> tuple[int, int, int, float]:
    """(bootloader instructions, application start-up instructions before its clock set-up,
    after it, estimated time to the first tick [ms])."""
    bc, sc, f = robot()
    b = BootBoard(elf, boot_elf, sc, f, bc)
    clock_init = b.cpu.symbols["stm32_clock_init"] & ~1
    counts = {"boot": 0, "app16": 0, "app180": 0}
    phase = ["boot"]

    def on_block(addr: int, n: int) -> None:
        if phase[0] == "boot" and 0x0800_8000 <= addr < SRAM_BASE:
            phase[0] = "app16"
        if addr == clock_init:
            phase[0] = "app180"  # at its end, rather: the set-up's own loops are few
        counts[phase[0]] += n

    b.cpu.on_block = on_block
    b.cpu.count_instructions(True)
    b.cpu.uc.ctl_flush_tb()  # blocks translated before the hook would not call it
    b.power_cycle()
    b.cpu.count_instructions(False)
    ms = (
        counts["boot"] * CPI / 16e6 + counts["app16"] * CPI / 16e6 + counts["app180"] * CPI / 180e6
    ) * 1e3 + 1.0  # SysTick's first period
    return counts["boot"], counts["app16"], counts["app180"], ms


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build", nargs="?", default=str(ROOT / "build-stm32"), help="the build")
    add_strict_flag(ap)
    args = ap.parse_args(argv)
    build = Path(args.build)
    elf, boot_elf = build / "asserv_stm32.elf", build / "asserv_boot.elf"
    goals = Goals("bench/update_stm32.py")
    print("| update of today's image over I2C (emulated, data-sheet flash) | 100 kHz | 400 kHz |")
    print("|---|---|---|")
    boot, app16, app180, ms = reset_to_tick(elf, boot_elf)
    rows: dict[str, list[str]] = {
        "image": [],
        "bus limit (9 bits a byte, the frames' bytes)": [],
    }
    for slot in ("B", "A"):
        rows[f"into slot {slot}: download (BEGIN .. header written)"] = []
        rows[f"into slot {slot}: START .. new application answering (+ start-up)"] = []
        rows[f"into slot {slot}: whole update (BOOTLOADER .. new application answering)"] = []
        rows[f"into slot {slot}: download / limit (goal {GOAL}x)"] = []
        rows[f"into slot {slot}: whole update / limit (goal {GOAL}x)"] = []
    for rate in (100_000, 400_000):
        updates = update_at(elf, boot_elf, rate)
        n = updates[0][3]
        limit = bus_limit_s(n, rate)
        rows["image"].append(f"{n} bytes")
        rows["bus limit (9 bits a byte, the frames' bytes)"].append(f"{limit:.2f} s")
        for slot, (down, start, whole, _) in zip(("B", "A"), updates, strict=True):
            into = f"into slot {slot}: "
            start += ms * 1e-3
            whole += ms * 1e-3
            rows[into + "download (BEGIN .. header written)"].append(f"{down:.2f} s")
            rows[into + "START .. new application answering (+ start-up)"].append(f"{start:.2f} s")
            rows[into + "whole update (BOOTLOADER .. new application answering)"].append(
                f"{whole:.2f} s"
            )
            for key, what, t in (
                (f"download / limit (goal {GOAL}x)", "download", down),
                (f"whole update / limit (goal {GOAL}x)", "whole update", whole),
            ):
                g = goals.check(
                    f"{what} into slot {slot} at {rate // 1000} kHz / bus limit",
                    t / limit,
                    "<=",
                    GOAL,
                )
                rows[into + key].append(f"{g.value:.2f}x, {g.mark}")
    for k, v in rows.items():
        print(f"| {k} | {v[0]} | {v[1]} |")
    print()
    print("| the bootloader | STM32F446RE |")
    print("|---|---|")
    print(f"| flash (sector 0, 16 KiB) | {flash_bytes(boot_elf)} bytes |")
    print(
        f"| reset to the first control tick | {ms:.1f} ms (estimate: {boot} instructions in the"
        f" bootloader at 16 MHz, {app16} + {app180} in the application's start-up, 1 ms SysTick) |"
    )
    print()
    for line in goals.lines():
        print(line)
    print(goals.summary())
    return goals.exit_code(args.strict)


if __name__ == "__main__":
    sys.exit(main())
