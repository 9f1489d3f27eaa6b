#!/usr/bin/env bash
# Held-out natural images for bench/design_tables.sh: greyscale sample images from Debian's python3-skimage
# package (installed with apt-get if missing), copied into build/heldout/ (never committed; build/ is ignored).
# These images are never used by `aosr design`: designs only see the instrument (telescope, AO, camera, r, N).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${1:-$root/build/heldout}"
skdata=/usr/lib/python3/dist-packages/skimage/data

if [[ ! -d "$skdata" ]]; then
  sudo_cmd=()
  if [[ $(id -u) -ne 0 ]]; then sudo_cmd=(sudo); fi
  echo "fetch_heldout: installing python3-skimage (for its sample images)" >&2
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends python3-skimage >&2
fi
[[ -d "$skdata" ]] || { echo "fetch_heldout: $skdata missing after install" >&2; exit 1; }

mkdir -p "$out"
# Single-channel (greyscale) sample images shipped by the package; the list is fixed so the tables are
# reproducible. camera: cameraman, 512x512; moon: lunar surface, 512x512; text: text on paper, 172x448;
# coins: Greek coins, 303x384. A missing one is reported and skipped.
copied=0
for name in camera.png moon.png coins.png text.png; do
  if [[ -f "$skdata/$name" ]]; then
    cp -f "$skdata/$name" "$out/$name"
    copied=$((copied + 1))
  else
    echo "fetch_heldout: $skdata/$name not shipped by this python3-skimage; skipped" >&2
  fi
done
[[ $copied -gt 0 ]] || { echo "fetch_heldout: no sample image found" >&2; exit 1; }
echo "fetch_heldout: $copied images in $out" >&2
ls -1 "$out"
