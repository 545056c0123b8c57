"""pytest set-up of the STM32 emulator harness: the modules beside this file, and the ELF
(ASSERV_STM32_ELF, default build-stm32/asserv_stm32.elf, which scripts/test.sh builds)."""

import os
import sys
from pathlib import Path

import pytest
from hypothesis import settings

# The tests assert behaviour, not speed (a loaded runner can take 1 s over a 1 ms example).
settings.register_profile("asserv", deadline=None, derandomize=True, database=None)
settings.load_profile("asserv")

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
ROOT = HERE.parents[1]


@pytest.fixture(scope="session")
def elf() -> Path:
    path = Path(os.environ.get("ASSERV_STM32_ELF", ROOT / "build-stm32" / "asserv_stm32.elf"))
    if not path.is_file():
        pytest.fail(
            f"{path}: no STM32 firmware; build it with: cmake -S firmware/ports/stm32 -B "
            "build-stm32 -DCMAKE_TOOLCHAIN_FILE=cmake/stm32f4.cmake && cmake --build build-stm32"
        )
    return path


@pytest.fixture(scope="session")
def boot_elf(elf: Path) -> Path:
    """The bootloader (firmware/boot/stm32), built beside the application (ASSERV_STM32_BOOT_ELF
    to override)."""
    path = Path(os.environ.get("ASSERV_STM32_BOOT_ELF", elf.parent / "asserv_boot.elf"))
    if not path.is_file():
        pytest.fail(f"{path}: no bootloader; it is built with the STM32 firmware (see above)")
    return path


@pytest.fixture(scope="session")
def elf_b(elf: Path) -> Path:
    """The application linked for the bootloader's slot B, built beside slot A's (``elf``)."""
    path = elf.parent / "asserv_stm32_b.elf"
    if not path.is_file():
        pytest.fail(f"{path}: no slot B image; it is built with the STM32 firmware (see above)")
    return path
