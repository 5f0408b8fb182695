"""SCons build script of the AgNav dev platform.

Three kinds of board, told apart by board.json's build.target:
  avr     ATmega2560 with Debian's gcc-avr / avr-libc; `-t upload` flashes with avrdude
  arm     STM32F405 with Debian's gcc-arm-none-eabi / newlib; `-t upload` flashes the ELF with
          OpenOCD through an ST-Link (SWD); boots under QEMU netduinoplus2
  native  the host gcc, for unit tests and the software-in-the-loop build
"""
import os
import shutil
from os.path import join

from SCons.Script import AlwaysBuild, Builder, Default, DefaultEnvironment

env = DefaultEnvironment()
board = env.BoardConfig()
target = board.get("build.target", "native")

COMMON_CFLAGS = ["-std=gnu11"]
COMMON_CCFLAGS = ["-Wall", "-Wextra", "-ffunction-sections", "-fdata-sections"]

if target == "avr":
    env.Replace(
        AR="avr-gcc-ar", AS="avr-gcc", CC="avr-gcc", CXX="avr-g++", GDB="avr-gdb",
        OBJCOPY="avr-objcopy", RANLIB="avr-gcc-ranlib", SIZETOOL="avr-size",
        PROGNAME="firmware", PROGSUFFIX=".elf",
        SIZEPROGREGEXP=r"^(?:\.text|\.data|\.bootloader)\s+(\d+).*",
        SIZEDATAREGEXP=r"^(?:\.data|\.bss|\.noinit)\s+(\d+).*",
        SIZECHECKCMD="$SIZETOOL -A -d $SOURCES",
        SIZEPRINTCMD="$SIZETOOL -A -d $SOURCES",
        UPLOADER="avrdude",
        UPLOADERFLAGS=[
            "-p", "$BOARD_MCU", "-c", "$UPLOAD_PROTOCOL", "-b", "$UPLOAD_SPEED",
            "-D", "-P", '"$UPLOAD_PORT"',
        ],
        UPLOADCMD="$UPLOADER $UPLOADERFLAGS -U flash:w:$SOURCES:i",
    )
    mcu_flags = ["-mmcu=$BOARD_MCU"]
    # Code size on the ATmega2560 (measured on the default build, see BENCHMARKS.md "Firmware"):
    #   -mrelax                   the linker shortens call/jmp to rcall/rjmp where they reach
    #   -mcall-prologues          register saves through shared prologue/epilogue routines
    #                             (a few cycles per call; the encoder ISR is assembly, unaffected)
    #   -mstrict-X                X only as a post-increment/decrement pointer: fewer address fix-ups
    #   -fno-move-loop-invariants hoisting raises register pressure on an 8-bit core: spills
    #   -fno-tree-loop-optimize   the loop transformations copy loop bodies for little gain here
    #   -fno-tree-vrp             value-range propagation duplicates paths (jump threading)
    #   -fno-inline-functions-called-once  LTO otherwise inlines every module's one-call
    #                             helpers into task_control/link_feed/main, where the register
    #                             pressure costs more code than the calls (and no tick time)
    # Together ~2.9 KB less flash than -Os -flto alone, and no longer control tick.
    # (-fno-inline-small-functions would save 0.4 KB more but costs ~2.4 k cycles per tick.)
    size_flags = [
        "-mrelax", "-mcall-prologues", "-mstrict-X", "-fno-move-loop-invariants", "-fno-tree-loop-optimize",
        "-fno-tree-vrp", "-fno-inline-functions-called-once",
    ]
    env.Append(
        CFLAGS=COMMON_CFLAGS,
        # -flto lets the encoder hook be inlined into the pin-change ISR (see hal/avr).
        CCFLAGS=COMMON_CCFLAGS + mcu_flags + ["-Os", "-flto"] + size_flags,
        # The assembler gets the MCU too (hal/avr/encoder_pcint_avr.S is avr6 code).
        ASFLAGS=mcu_flags,
        CPPDEFINES=[("F_CPU", "$BOARD_F_CPU")],
        LINKFLAGS=mcu_flags + [
            "-Os", "-flto", *size_flags, "-Wl,--gc-sections",
            "-Wl,-Map," + join("$BUILD_DIR", "${PROGNAME}.map"),  # tools/fw_size.py reads it
        ],
        BUILDERS=dict(
            ElfToHex=Builder(
                action=env.VerboseAction(
                    "$OBJCOPY -O ihex -R .eeprom $SOURCES $TARGET", "Building $TARGET"
                ),
                suffix=".hex",
            )
        ),
    )
elif target == "arm":
    env.Replace(
        AR="arm-none-eabi-gcc-ar", AS="arm-none-eabi-gcc", CC="arm-none-eabi-gcc",
        CXX="arm-none-eabi-g++", GDB="gdb-multiarch", OBJCOPY="arm-none-eabi-objcopy",
        RANLIB="arm-none-eabi-gcc-ranlib", SIZETOOL="arm-none-eabi-size",
        PROGNAME="firmware", PROGSUFFIX=".elf",
        SIZEPROGREGEXP=r"^(?:\.text|\.data|\.rodata|\.isr_vector)\s+(\d+).*",
        SIZEDATAREGEXP=r"^(?:\.data|\.bss|\.noinit)\s+(\d+).*",
        SIZECHECKCMD="$SIZETOOL -A -d $SOURCES",
        SIZEPRINTCMD="$SIZETOOL -A -d $SOURCES",
    )
    cpu_flags = [
        "-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16",
    ]
    # PlatformIO passes board.json's build.ldscript to the linker as LDSCRIPT_PATH.
    env.Replace(LDSCRIPT_PATH=join("$PROJECT_DIR", board.get("build.ldscript", "")))
    env.Append(
        CFLAGS=COMMON_CFLAGS,
        CCFLAGS=COMMON_CCFLAGS + cpu_flags + ["-Os"],
        ASFLAGS=cpu_flags,
        CPPDEFINES=[("F_CPU", "$BOARD_F_CPU"), "STM32F405xx"],
        LINKFLAGS=cpu_flags + [
            "-Os", "-Wl,--gc-sections", "-nostartfiles", "--specs=nano.specs",
        ],
        LIBS=["c", "m", "gcc", "nosys"],
        # Raw images for USB DFU recovery (docs/stm32.md), one per flash region the ELF loads: the
        # vectors (sector 0) and the code from sector 3 on. A single objcopy image would span the
        # gap between them, the emulated EEPROM in sectors 1-2, as zeros.
        BUILDERS=dict(
            ElfToVectorsBin=Builder(
                action=env.VerboseAction("$OBJCOPY -O binary -j .isr_vector $SOURCES $TARGET",
                                         "Building $TARGET"),
                suffix=".bin",
            ),
            ElfToCodeBin=Builder(
                action=env.VerboseAction("$OBJCOPY -O binary -R .isr_vector $SOURCES $TARGET",
                                         "Building $TARGET"),
                suffix=".bin",
            ),
        ),
    )
    # Upload (board upload.protocol "stlink"): OpenOCD's `program` writes the ELF's loadable
    # segments only, erasing just the sectors they cover (flash write_image erase), so the EEPROM
    # sectors 1-2 between the vectors and the code keep calibration, parameters and the signing
    # key. AGNAV_OPENOCD names another openocd binary (tests point it at a recorder).
    env.Replace(
        UPLOADER=os.environ.get("AGNAV_OPENOCD", "openocd"),
        UPLOADERFLAGS=[
            "-f", board.get("upload.openocd_interface", "interface/stlink.cfg"),
            "-f", board.get("upload.openocd_target", "target/stm32f4x.cfg"),
        ],
        UPLOADCMD='$UPLOADER $UPLOADERFLAGS -c "program {$SOURCE} verify reset exit"',
    )
else:
    env.Replace(PROGNAME="program", SIZETOOL="size", SIZEPRINTCMD="$SIZETOOL $SOURCES")
    env.Append(
        CFLAGS=COMMON_CFLAGS,
        CCFLAGS=COMMON_CCFLAGS + ["-O1", "-g"],
        LIBS=["m"],
    )

if target == "arm":
    # Start-up code and vector table, linked into every ARM image (firmware and each
    # unit test) like a framework's core would be; see firmware/boot/.
    env.BuildSources(join("$BUILD_DIR", "boot"), join("$PROJECT_DIR", board.get("build.startup")))

target_elf = env.BuildProgram()
default_targets = [target_elf]

if target == "avr":
    target_hex = env.ElfToHex(join("$BUILD_DIR", "${PROGNAME}"), target_elf)
    default_targets.append(target_hex)
    env.AddPlatformTarget(
        "upload",
        target_hex,
        [
            env.VerboseAction(env.AutodetectUploadPort, "Looking for upload port..."),
            env.VerboseAction("$UPLOADCMD", "Uploading $SOURCE"),
        ],
        "Upload",
    )
elif target == "arm":
    default_targets.append(env.ElfToVectorsBin(join("$BUILD_DIR", "${PROGNAME}.vectors.bin"), target_elf))
    default_targets.append(env.ElfToCodeBin(join("$BUILD_DIR", "${PROGNAME}.code.bin"), target_elf))

    def check_uploader(target, source, env):  # noqa: ARG001 (SCons action signature)
        protocol = env.subst("$UPLOAD_PROTOCOL")
        if protocol != "stlink":
            print(f"upload_protocol {protocol!r}: this board uploads with 'stlink' (OpenOCD, docs/stm32.md)")
            return 1
        tool = env.subst("$UPLOADER")
        if shutil.which(tool) is None:
            print(f"{tool}: not found. Install OpenOCD (Debian: sudo apt-get install openocd) and connect "
                  "an ST-Link to the board's SWD pins (docs/stm32.md).")
            return 1
        return 0

    env.AddPlatformTarget(
        "upload",
        target_elf,
        [
            env.VerboseAction(check_uploader, "Checking $UPLOADER"),
            env.VerboseAction("$UPLOADCMD", "Uploading $SOURCE"),
        ],
        "Upload",
    )

env.AddPlatformTarget(
    "size", target_elf, env.VerboseAction("$SIZEPRINTCMD", "Calculating size $SOURCE"),
    "Program Size",
)
AlwaysBuild(env.Alias("nobuild", target_elf))
Default(default_targets)
