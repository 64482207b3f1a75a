#!/usr/bin/env bash
# The studio's browser test (tests/all/studio.rs → tests/browser/studio.test.mjs): Debian's
# chromium (headless; WebGPU on SwiftShader), Node.js, and puppeteer-core from the committed
# package-lock.json (puppeteer-core never downloads a browser).
set -euo pipefail
cd "$(dirname "$0")/../.."
missing=()
command -v chromium >/dev/null 2>&1 || missing+=(chromium)
command -v node >/dev/null 2>&1 || missing+=(nodejs)
command -v npm >/dev/null 2>&1 || missing+=(npm)
if [ ${#missing[@]} -gt 0 ]; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}"
fi
if [ ! -d tests/browser/node_modules/puppeteer-core ]; then
  (cd tests/browser && npm ci --no-audit --no-fund)
fi
