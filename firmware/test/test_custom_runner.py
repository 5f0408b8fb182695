"""PlatformIO test runner for AgNav.

Unity's own runner asks the PlatformIO registry for throwtheswitch/Unity, which
is unreachable on the build machines. This runner keeps Unity's output parsing
and takes Unity from ../shared/deps/Unity-2.6.0.tar.gz when that unmodified
upstream archive is present (the registry package otherwise). Embedded targets
run through `test_testing_command` (simavr harness for the AVR, QEMU for the
STM32), which this runner builds on demand.
"""
import os
import subprocess

from platformio.test.runners.unity import UnityTestRunner

UNITY_REGISTRY_SPEC = "throwtheswitch/Unity@2.6.0"


def _project_dir():
    return os.getcwd()


def unity_lib_spec():
    override = os.environ.get("AGNAV_UNITY_ARCHIVE")
    candidates = [override] if override else []
    candidates.append(
        os.path.join(_project_dir(), "..", "shared", "deps", "Unity-2.6.0.tar.gz")
    )
    for path in candidates:
        if path and os.path.isfile(path):
            return "Unity=file://" + os.path.abspath(path)
    return UNITY_REGISTRY_SPEC


class CustomTestRunner(UnityTestRunner):
    EXTRA_LIB_DEPS = [unity_lib_spec()]

    def stage_testing(self):
        command = self.project_config.get(
            f"env:{self.test_suite.env_name}", "test_testing_command"
        )
        if command and command[0].endswith("build/bin/avr_harness"):
            # The simavr harness is a small C program of ours, built once.
            subprocess.run(
                ["make", "-s", "-C", _project_dir(), "build/bin/avr_harness"], check=True
            )
        return super().stage_testing()
