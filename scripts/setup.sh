#!/usr/bin/env bash
# Installs the Debian packages brdf-rig needs to build and test (the only downloads: Debian's).
#   libclang-dev        bindgen, for the V4L2 bindings of the webcam/v4l2 camera backends
#   libudev-dev         serialport's udev feature (port enumeration)
#   pkg-config          finds libudev
#   gcc-avr avr-libc    builds the reference firmware for the ATmega2560
#   qemu-system-misc    qemu-system-avr, runs that firmware in the tests
#   chromium            headless browser for the HTML report test and the lab page tests
#   chromium-driver     chromedriver (WebDriver), to click through the lab page in the tests
set -euo pipefail
pkgs=(libclang-dev libudev-dev pkg-config gcc-avr avr-libc binutils-avr qemu-system-misc chromium chromium-driver)
missing=()
for p in "${pkgs[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all system packages present"
  exit 0
fi
echo "setup: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
