#!/usr/bin/env bash
# Make sure a headless Chromium is available for the report test (tests/test_report_browser.py).
# Uses Debian's package when missing and we may install (root, apt-get present). Prints the path.
set -euo pipefail
for exe in chromium chromium-browser google-chrome; do
  if command -v "$exe" >/dev/null 2>&1; then command -v "$exe"; exit 0; fi
done
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
  echo "installing Debian's chromium for the report test..." >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq >/dev/null
  apt-get install -y -qq chromium >/dev/null
  command -v chromium
  exit 0
fi
echo "no chromium found and cannot install it (need root + apt-get); install chromium by hand" >&2
exit 1
