#!/usr/bin/env bash
# Make sure the system libraries for off-screen rendering are present: libEGL (+ the Mesa EGL vendor)
# and Mesa's DRI drivers (software rasteriser swrast/llvmpipe). PyVista renders through VTK's EGL
# window (cadfeat.render.scene), so no X server or xvfb is needed.
# Also Debian's libllvm19: Mitsuba's LLVM variant (llvm_ad_rgb, ~10x its scalar variant) loads libLLVM at run time;
# without it the physically based renderer falls back to scalar_rgb (cadfeat.render.pbr).
# Installs Debian's packages quietly when missing and we may (root + apt-get); exit 1 otherwise.
set -euo pipefail
missing=()
have_lib() { ldconfig -p 2>/dev/null | grep -q "$1" || compgen -G "/usr/lib/*/$1*" >/dev/null || compgen -G "/usr/lib/$1*" >/dev/null; }
have_lib libEGL.so.1 || missing+=(libegl1)
have_lib libEGL_mesa.so.0 || missing+=(libegl-mesa0)
compgen -G "/usr/lib/*/dri/swrast_dri.so" >/dev/null || compgen -G "/usr/lib/*/dri/*_dri.so" >/dev/null \
  || compgen -G "/usr/lib/dri/*_dri.so" >/dev/null || missing+=(libgl1-mesa-dri)
optional=()
have_lib libLLVM.so.19 || optional+=(libllvm19)
if [ ${#missing[@]} -eq 0 ] && [ ${#optional[@]} -eq 0 ]; then
  exit 0
fi
missing+=("${optional[@]}")
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
  echo "installing ${missing[*]} for off-screen rendering..." >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq >/dev/null
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  exit 0
fi
if [ ${#missing[@]} -eq ${#optional[@]} ]; then
  echo "note: ${optional[*]} missing (no root/apt-get): physically based renders use Mitsuba's slower scalar variant" >&2
  exit 0
fi
echo "missing system packages for off-screen rendering: ${missing[*]} (need root + apt-get to install;" \
     "install them by hand: apt-get install ${missing[*]})" >&2
exit 1
