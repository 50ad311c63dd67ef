# Sourced by the report tests: renders PAGE in headless Chromium and checks it as a reader
# would see it. Defines `render_page PAGE WORK HEIGHT CHECK MIN_PLOTS`: a screenshot at 1200 x
# HEIGHT (WORK/shot.png), no console message (an exception, a failed load, an error logged by
# the page), then the page's own layout list (#layout: id x y width height of each plot) given
# to CHECK (report_screenshot_check) with the plots it must find. Sets `headless` (the browser
# command) for a caller that takes another screenshot. Exits 77 (skipped) when no Chromium
# is installed, after the caller's checks that need none.
render_page() {
  local page=$1 work=$2 height=$3 check=$4 plots=$5
  local browser
  browser=$(command -v chromium || command -v chromium-browser || true)
  if [ -z "$browser" ]; then
    echo "chromium is not installed (scripts/setup installs it): the page was checked, not rendered"
    exit 77
  fi
  headless=("$browser" --headless --no-sandbox --disable-gpu --hide-scrollbars --no-first-run
            --user-data-dir="$work/profile" --window-size=1200,"$height")
  timeout 120 "${headless[@]}" --enable-logging=stderr --v=0 --screenshot="$work/shot.png" "file://$page" \
    > "$work/chromium.log" 2>&1 || fail "chromium failed: $(tail -5 "$work/chromium.log")"
  # Console messages come as ":INFO:CONSOLE(line)] "text"".
  if grep -qE ':CONSOLE[:(]' "$work/chromium.log"; then
    fail "console messages: $(grep -E ':CONSOLE[:(]' "$work/chromium.log" | head -5)"
  fi
  timeout 120 "${headless[@]}" --dump-dom "file://$page#layout" > "$work/dom.html" 2> "$work/chromium_dom.log" \
    || fail "chromium --dump-dom failed"
  sed -n '/<pre id="layout">/,/<\/pre>/p' "$work/dom.html" | sed -E 's/<[^>]*>//g' > "$work/layout.txt"
  echo "plots on the page (id x y width height):"
  cat "$work/layout.txt"
  "$check" "$work/shot.png" "$work/layout.txt" "$plots"
}
