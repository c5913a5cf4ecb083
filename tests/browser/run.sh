#!/usr/bin/env bash
# Browser test of the 3D pages (issue 18): builds a configuration page (analyze --view),
# a workspace page (coarse sweep) and an optimizer report page (designs.html of a
# 2-candidate search), opens each in headless chromium, fails on any console error or
# uncaught exception, and checks the screenshot shows the robot (check_page.py).
# Installs Debian's chromium when missing (as root with apt-get); skips, saying so, where
# no browser can be installed. Screenshots and pages stay in $TDPCR_BROWSER_OUT (default:
# a fresh temporary directory).
set -euo pipefail
cd "$(dirname "$0")/../.."

find_browser() {
  for b in chromium chromium-browser google-chrome; do
    if command -v "$b" >/dev/null 2>&1; then command -v "$b"; return 0; fi
  done
  return 1
}

if ! browser=$(find_browser); then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "browser test: installing chromium (apt-get)"
    apt-get install -y chromium >/dev/null 2>&1 ||
      { apt-get update >/dev/null 2>&1 && apt-get install -y chromium >/dev/null 2>&1; } || true
  fi
  if ! browser=$(find_browser); then
    echo "browser test SKIPPED: no chromium found and none could be installed" \
         "(needs root and apt-get); the 3D pages were not checked in a browser"
    exit 0
  fi
fi
if ! command -v python3 >/dev/null 2>&1; then
  echo "browser test SKIPPED: python3 (which drives chromium) is missing"
  exit 0
fi

out=${TDPCR_BROWSER_OUT:-$(mktemp -d -t tdpcr-browser-XXXXXX)}
# chromium's own messages, every launch appended (for a browser that fails to start).
export CHROMIUM_LOG=${CHROMIUM_LOG:-$out/chromium.log}
mkdir -p "$out"
# The CLIs as `cargo test` builds them (test profile, opt-level 2: the sweeps are fast): a
# no-op after the README's test command has run `cargo test`; a plain `cargo build` would
# compile every dependency again with other features.
cargo test --workspace --no-run -q
bin=target/debug
check="python3 tests/browser/check_page.py $browser"

# The checker must be able to fail: a page that throws, and a blank page.
printf '<!DOCTYPE html><html><body><script>throw new Error("boom")</script></body></html>' \
  > "$out/throws.html"
printf '<!DOCTYPE html><html><body><script>document.body.dataset.rendered="yes"</script></body></html>' \
  > "$out/blank.html"
for bad in throws blank; do
  if $check "$out/$bad.html" "$out/$bad.png" > "$out/$bad.log" 2>&1; then
    echo "browser test FAILED: the checker accepted $bad.html"; cat "$out/$bad.log"; exit 1
  fi
done

"$bin/tdpcr" analyze designs/lilge2022.ron --q 0.004,0.02,-0.003,-0.01,0.002,0.03 \
  --view "$out/analyze.html" > /dev/null
"$bin/tdpcr" workspace designs/lilge2022.ron --step 0.01 --angle-step 0.5 \
  --z-range -0.02,0.02 --out "$out/workspace" > /dev/null
# The default search without its slice figures (a finer sweep of two designs): 2 candidates.
sed -e "s|\"../designs/|\"$PWD/designs/|" -e 's|figures: Some(FigureSweep([^)]*)),|figures: None,|' \
  optim/default.ron > "$out/optim.ron"
grep -q "figures: None" "$out/optim.ron"
"$bin/tdpcr-optim" "$out/optim.ron" --budget-evals 2 --out "$out/optim" > /dev/null

status=0
$check "$out/analyze.html" "$out/analyze.png" || status=1
$check "$out/workspace/workspace.html" "$out/workspace.png" || status=1
# Two scenes side by side: something drawn in each half.
$check "$out/optim/designs.html" "$out/optim-left.png" --region 0.05,0.15,0.45,0.9 || status=1
$check "$out/optim/designs.html" "$out/optim-right.png" --region 0.55,0.15,0.95,0.9 || status=1
if [ "$status" = 0 ]; then
  echo "browser test passed (pages and screenshots in $out)"
else
  echo "browser test FAILED (pages and screenshots in $out)"
fi
exit "$status"
