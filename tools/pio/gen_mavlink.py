"""PlatformIO pre-build script: generate the MAVLink C headers from protocol/agnav.xml
into build/mavlink/c (never committed) and put them on the include path."""
import os
import subprocess

Import("env")  # noqa: F821  (SCons injects it)

project_dir = env.subst("$PROJECT_DIR")  # noqa: F821
out_dir = os.path.join(project_dir, "build", "mavlink")
subprocess.run(
    [env.subst("$PYTHONEXE"), os.path.join(project_dir, "protocol", "generate.py"),  # noqa: F821
     "--lang", "c", "--out", out_dir],
    check=True,
    stdout=subprocess.DEVNULL,
)
include = os.path.join(out_dir, "c")
# Library environments are cloned from this one later, so they inherit the flag.
env.Append(CCFLAGS=["-isystem", include])  # noqa: F821  (system: its warnings are not ours)
# Also on CPPPATH so SCons' scanner sees the generated headers and rebuilds what includes them
# when they change (gcc ignores -I for a directory that is also given with -isystem).
env.Append(CPPPATH=[include])  # noqa: F821
# The shared byte vectors as Unity tests (firmware/test/test_protocol_vectors).
subprocess.run(
    [env.subst("$PYTHONEXE"), os.path.join(project_dir, "protocol", "vectors_to_c.py"),  # noqa: F821
     os.path.join(include, "agnav_vectors_test.h")],
    check=True,
)
