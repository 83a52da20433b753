#!/usr/bin/env bash
# Install the toolchains the firmware needs (Debian/Ubuntu): avr-gcc, avr-libc,
# binutils-avr, avrdude for the ATmega2560 build; g++ and make for the native unit
# tests; clang with its runtime (libFuzzer, sanitizers) for the fuzz target; simavr,
# libsimavr-dev, libelf-dev and pkg-config for the firmware-in-the-loop harness
# (firmware/sim/, no GL or X libraries needed); strace for the tests that kill a run
# inside a write system call (fault injection, tests/store/test_kill_anywhere.py); python3-venv
# when the python3 on PATH cannot make a virtual environment (Debian's, without it).
# Idempotent: does nothing when all are installed; runs apt-get update only when
# something is missing. Non-interactive; uses sudo when not root.
set -euo pipefail

PACKAGES=(gcc-avr avr-libc binutils-avr avrdude g++ make clang libclang-rt-14-dev
          simavr libsimavr-dev libelf-dev pkg-config strace)
# The README's `python3 -m venv`: Debian's python3 has no ensurepip without python3-venv.
if ! python3 -c "import ensurepip" >/dev/null 2>&1; then
    PACKAGES+=(python3-venv)
fi

missing=()
for pkg in "${PACKAGES[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$pkg")
    fi
done

if [ ${#missing[@]} -eq 0 ]; then
    echo "firmware toolchain present: ${PACKAGES[*]}"
    exit 0
fi

if [ "$(id -u)" -eq 0 ]; then
    SUDO=()
elif command -v sudo >/dev/null 2>&1; then
    SUDO=(sudo)
else
    echo "need root (or sudo) to install: ${missing[*]}" >&2
    exit 1
fi

echo "installing: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
${SUDO[@]+"${SUDO[@]}"} apt-get update -q
${SUDO[@]+"${SUDO[@]}"} apt-get install -y -q --no-install-recommends "${missing[@]}"
