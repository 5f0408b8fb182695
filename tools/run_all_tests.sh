#!/usr/bin/env bash
# Every AgNav test suite, then one closing line "N passed, N failed" adding them all up:
#   pytest            host library and hil/ (first light, SIL scenarios)
#   pio test native   firmware unit tests on the PC (ASan + UBSan)
#   pio test megaatmega2560   the same tests on the ATmega2560 under simavr
#   pio test stm32f405        the same tests on the STM32F405 under QEMU netduinoplus2
#   static checks     ruff check and mypy --strict (tools/static_checks.py), one case each
# Called by `make test` (after `make setup`) and by .ci/run.
set -u
cd "$(dirname "$0")/.."
export PLATFORMIO_CORE_DIR="$PWD/.pio-core" PLATFORMIO_DISABLE_UPGRADE_CHECK=true
export PLATFORMIO_SETTING_ENABLE_TELEMETRY=No PLATFORMIO_NO_ANSI=true
REPORTS=build/test-reports
rm -rf "$REPORTS"
mkdir -p "$REPORTS"
status=0

for env in native megaatmega2560 stm32f405; do
  echo "=== firmware unit tests: $env ==="
  .venv/bin/pio test -e "$env" --json-output-path "$REPORTS/pio-$env.json" || status=1
done

echo "=== host and hil tests: pytest ==="
.venv/bin/pytest -q --junitxml="$REPORTS/pytest.xml" || status=1

echo "=== static checks: ruff, mypy ==="
.venv/bin/python tools/static_checks.py "$REPORTS" || status=1

.venv/bin/python tools/sum_test_reports.py "$REPORTS" || status=1
exit $status
