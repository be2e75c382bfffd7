#!/usr/bin/env bash
# Rebuild azee_mj/export/vendor/three.min.js: three.js with GLTFLoader and OrbitControls as
# one minified script that sets window.THREE, window.GLTFLoader and window.OrbitControls.
# The web player inlines it, so a player page needs no network. Needs node and npm.
set -euo pipefail
THREE_VERSION="${THREE_VERSION:-0.187.0}"
ESBUILD_VERSION="${ESBUILD_VERSION:-0.28.2}"
out="$(cd "$(dirname "$0")/.." && pwd)/azee_mj/export/vendor"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
npm init -y >/dev/null
npm install --no-audit --no-fund "three@$THREE_VERSION" "esbuild@$ESBUILD_VERSION" >/dev/null
cat > entry.js <<'JS'
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
window.THREE = THREE;
window.GLTFLoader = GLTFLoader;
window.OrbitControls = OrbitControls;
JS
./node_modules/.bin/esbuild entry.js --bundle --minify --format=iife --legal-comments=none \
  --outfile="$out/three.min.js"
cp node_modules/three/LICENSE "$out/LICENSE-three.txt"
echo "three.js $THREE_VERSION bundled to $out/three.min.js"
