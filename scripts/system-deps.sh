#!/usr/bin/env bash
# Installs the Debian packages the rendering tests and the demo need, when they are missing.
# Offscreen OpenGL runs on Mesa's llvmpipe through EGL; the desktop demo's tests run in Xvfb.
set -euo pipefail

packages=(libegl1 libegl-mesa0 libgl1-mesa-dri xvfb xauth)
missing=()
for p in "${packages[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null; then
    echo "installing Debian packages: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
    echo "warning: missing Debian packages ${missing[*]}; rendering tests will be skipped." >&2
    echo "         install them with: sudo apt-get install ${missing[*]}" >&2
fi
