"""PlatformIO library script (hal/library.json "extraScript"): the AgNav platform hands -mmcu to
the C compiler only, so the hand-written AVR vector (avr/encoder_pcint_avr.S) would be assembled
for the default avr2 core, which the avr6 link refuses. Only the hal library's own build is touched."""
Import("env")  # noqa: F821  (SCons)

if env.get("BOARD_MCU") and env.subst("$CC").startswith("avr-"):  # noqa: F821
    env.Append(ASFLAGS=["-mmcu=$BOARD_MCU"])  # noqa: F821
