#!/usr/bin/env bash
# Installs what ipm needs on a fresh Debian machine (run as root or with sudo available):
#  - libLLVM 19 for Mitsuba's llvm_ad_rgb variant (LLVM 15 aborts on the first render,
#    LLVM 14 is refused);
#  - torch/torchvision pinned first, so pip takes the build this machine has on disk instead
#    of downloading gigabytes;
#  - ipm itself, editable, with the test and docs tools (pytest, ruff, mkdocs).
set -euo pipefail
cd "$(dirname "$0")/.."
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
if ! ls /usr/lib/*/libLLVM.so.19* >/dev/null 2>&1 && ! ls /usr/lib/llvm-19/lib/libLLVM* >/dev/null 2>&1; then
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libllvm19 >/dev/null
fi
export PIP_ROOT_USER_ACTION=ignore
python3 -m pip install -q "torch==2.14.1" "torchvision==0.29.1"
python3 -m pip install -q -e ".[dev,ray]"
python3 -c "import ipm" && echo "ipm installed: $(command -v ipm)"
