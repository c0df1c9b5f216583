#!/usr/bin/env bash
# Runs every cargo-fuzz target briefly (FUZZ_SECONDS each, 5 by default) from its corpus, after
# building the corpora (seed.sh) and the targets. Any crash, hang (over 1 s per input, 5 s for
# the OSM target) or memory
# blow-up (over 1024 MB) fails the script, and libFuzzer leaves the input in
# tests/fuzz/artifacts/TARGET/.
#
# Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz --locked`). Without them
# it skips loudly (stderr, and a line in $BLOCKWALK_SKIP_LOG that tests/run counts) and exits 0,
# unless BLOCKWALK_REQUIRE names `fuzz` (or is `all`) or BLOCKWALK_REQUIRE_FUZZ=1: then it fails.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
secs="${FUZZ_SECONDS:-5}"
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
    why="\`cargo +nightly fuzz\` is not available (rustup toolchain install nightly; cargo install cargo-fuzz --locked)"
    case ",${BLOCKWALK_REQUIRE:-},${BLOCKWALK_REQUIRE_FUZZ:-}," in
        *,fuzz,*|*,all,*|*,1,)
            echo "tests/fuzz/ci.sh: $why, and fuzz is required (BLOCKWALK_REQUIRE)" >&2; exit 1 ;;
    esac
    echo "SKIPPED [fuzz] tests/fuzz/ci.sh: $why (BLOCKWALK_REQUIRE=fuzz makes this a failure)" >&2
    if [ -n "${BLOCKWALK_SKIP_LOG:-}" ]; then
        printf 'fuzz\ttests/fuzz/ci.sh\t%s\n' "$why" >>"$BLOCKWALK_SKIP_LOG"
    fi
    exit 0
fi
flags=(--fuzz-dir "$here" --sanitizer none --debug-assertions)
"$here/seed.sh" >/dev/null
start=$(date +%s)
cargo +nightly fuzz build "${flags[@]}"
echo "fuzz targets built in $(( $(date +%s) - start )) s"
failed=()
mkdir -p "$here/artifacts"
for t in $(cargo +nightly fuzz list --fuzz-dir "$here"); do
    log="$here/artifacts/ci-$t.log"
    # The OSM seed is 685 KB: one read of it takes 0.2 s of CPU, over 1 s of wall clock on a
    # loaded machine.
    timeout=1
    if [ "$t" = osm_pbf ]; then timeout=5; fi
    dict=()
    if [ -f "$here/dicts/$t.dict" ]; then dict=(-dict="$here/dicts/$t.dict"); fi
    if cargo +nightly fuzz run "${flags[@]}" "$t" -- \
            -max_total_time="$secs" -timeout="$timeout" -rss_limit_mb=1024 -print_final_stats=1 \
            "${dict[@]}" >"$log" 2>&1; then
        echo "$t: $(grep -Eo 'number_of_executed_units: *[0-9]+' "$log" | grep -Eo '[0-9]+$') runs"
    else
        failed+=("$t")
        tail -n 40 "$log" >&2
    fi
done
echo "fuzz targets built and run in $(( $(date +%s) - start )) s"
if [ ${#failed[@]} -gt 0 ]; then
    echo "FAILED fuzz targets: ${failed[*]} (inputs in $here/artifacts/)" >&2
    exit 1
fi
echo "every fuzz target ran ${secs} s without a finding"
