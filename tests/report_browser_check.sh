#!/usr/bin/env bash
# Renders a scenecal HTML report in headless Chromium and checks the result.
#
#   tests/report_browser_check.sh REPORT.html OUT.png
#
# Checks:
#  - the HTML has no external reference (http://, https://, src="//, url( )
#    and the sections of its kind: a calibration report (#summary,
#    #convergence, #cost-slices, #overlays) or an experiment report
#    (#summary, #box-plots, #per-dof-errors, #runs), inline <svg> plots, and
#    for calibration reports PNG overlays as data: URIs;
#  - the screenshot is not blank: grey-level spread and several distinct colours.
# Image statistics come from the report_image_stats helper when
# REPORT_IMAGE_STATS names it (built with the tests), else from a small
# pure-python PNG decoder (slower).
# Exit codes: 0 pass, 1 fail, 2 usage, 77 chromium absent (ctest SKIP_RETURN_CODE).
set -euo pipefail

if [[ $# -ne 2 ]]; then
  echo "usage: $0 REPORT.html OUT.png" >&2
  exit 2
fi
report=$(realpath "$1")
screenshot=$(realpath -m "$2")
[[ -f "$report" ]] || { echo "FAIL: no report at $report" >&2; exit 1; }

chromium_bin=${CHROMIUM:-/usr/bin/chromium}
if [[ ! -x "$chromium_bin" ]]; then
  echo "SKIP: $chromium_bin not found (apt-get install chromium, or set CHROMIUM)" >&2
  exit 77
fi

# 1. The page itself.
python3 - "$report" <<'PY'
import re, sys
path = sys.argv[1]
html = open(path, encoding="utf-8").read()
problems = []
for bad in ("http://", "https://", 'src="//', "src='//", "url(", "<script", "<link", "@import"):
    if bad in html.lower():
        problems.append(f"external reference or script: {bad!r}")
ids = set(re.findall(r'<section id="([^"]+)"', html))
if "convergence" in ids:
    kind, wanted = "calibration", ["summary", "convergence", "cost-slices", "overlays"]
elif "box-plots" in ids:
    kind, wanted = "experiment", ["summary", "box-plots", "per-dof-errors", "runs"]
else:
    kind, wanted = "unknown", ["summary"]
    problems.append(f"neither a calibration nor an experiment report (sections: {sorted(ids)})")
for section in wanted:
    if section not in ids:
        problems.append(f"missing section #{section}")
svgs = html.count("<svg")
if svgs < 2:
    problems.append(f"only {svgs} <svg> plots")
images = len(re.findall(r'<img [^>]*src="data:image/png;base64,[A-Za-z0-9+/=]{100,}"', html))
if kind == "calibration" and images < 1:
    problems.append("no PNG overlay embedded as a data: URI")
if not re.search(r"<table>.*?<td", html, re.S):
    problems.append("no table with data")
if problems:
    print("FAIL: " + path + ": " + "; ".join(problems), file=sys.stderr)
    sys.exit(1)
print(f"html ok: {kind} report, sections {sorted(ids)}, {svgs} <svg>, {images} embedded PNG(s)")
PY

# 2. Render it.
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
rm -f "$screenshot"
timeout 120 "$chromium_bin" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
  --disable-background-networking --disable-component-update --disable-sync --hide-scrollbars \
  --user-data-dir="$profile" --screenshot="$screenshot" --window-size=1400,3000 "file://$report" \
  >"$profile/chromium.log" 2>&1 || true
if [[ ! -s "$screenshot" ]]; then
  echo "FAIL: chromium wrote no screenshot; its log:" >&2
  tail -20 "$profile/chromium.log" >&2
  exit 1
fi

# 3. The screenshot is not blank.
if [[ -n "${REPORT_IMAGE_STATS:-}" && -x "${REPORT_IMAGE_STATS}" ]]; then
  stats=$("$REPORT_IMAGE_STATS" "$screenshot")
else
  stats=$(python3 - "$screenshot" <<'PY'
import struct, sys, zlib
data = open(sys.argv[1], "rb").read()
assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
pos, idat, width = 8, b"", 0
while pos < len(data):
    length, kind = struct.unpack(">I4s", data[pos:pos + 8])
    body = data[pos + 8:pos + 8 + length]
    if kind == b"IHDR":
        width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
        assert depth == 8 and colour in (2, 6) and interlace == 0, "unsupported PNG layout"
        channels = 3 if colour == 2 else 4
    elif kind == b"IDAT":
        idat += body
    pos += 12 + length
raw = zlib.decompress(idat)
stride = width * channels
previous = bytearray(stride)
grey_sum = grey_sq = 0.0
colours, non_white, count = set(), 0, 0
for row in range(height):
    start = row * (stride + 1)
    kind, line = raw[start], bytearray(raw[start + 1:start + 1 + stride])
    for i in range(stride):
        left = line[i - channels] if i >= channels else 0
        up = previous[i]
        upper_left = previous[i - channels] if i >= channels else 0
        if kind == 1: line[i] = (line[i] + left) & 255
        elif kind == 2: line[i] = (line[i] + up) & 255
        elif kind == 3: line[i] = (line[i] + ((left + up) >> 1)) & 255
        elif kind == 4:
            p = left + up - upper_left
            pa, pb, pc = abs(p - left), abs(p - up), abs(p - upper_left)
            line[i] = (line[i] + (left if pa <= pb and pa <= pc else up if pb <= pc else upper_left)) & 255
    previous = line
    if row % 2:
        continue
    for i in range(0, stride, channels * 2):
        r, g, b = line[i], line[i + 1], line[i + 2]
        grey = 0.299 * r + 0.587 * g + 0.114 * b
        grey_sum += grey; grey_sq += grey * grey; count += 1
        colours.add(((b >> 3) << 10) | ((g >> 3) << 5) | (r >> 3))
        non_white += r < 245 or g < 245 or b < 245
mean = grey_sum / count
print(f"{width} {height} {max(0.0, grey_sq / count - mean * mean) ** 0.5:.3f} {len(colours)} {non_white / count:.4f}")
PY
)
fi
read -r width height stddev colours non_white <<<"$stats"
echo "screenshot $screenshot: ${width}x${height}, grey stddev $stddev, $colours distinct colours, non-white fraction $non_white"
python3 - "$stddev" "$colours" "$non_white" <<'PY'
import sys
stddev, colours, non_white = float(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
problems = []
if stddev < 10: problems.append(f"grey stddev {stddev} < 10")
if colours < 32: problems.append(f"{colours} distinct colours < 32")
if non_white < 0.05: problems.append(f"non-white fraction {non_white} < 0.05")
if problems:
    print("FAIL: screenshot looks blank: " + "; ".join(problems), file=sys.stderr)
    sys.exit(1)
print("screenshot ok")
PY
