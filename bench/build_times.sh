#!/usr/bin/env bash
# Compile-time profile of aosr (bench/results/build.md): configures a fresh build folder whose compiler launcher
# times every translation unit, builds the default target (command 1's) and then aosr_dev (command 2's), and
# prints wall times per step and the slowest translation units.
# Usage: bench/build_times.sh [BUILD_DIR (default /tmp/aosr-build-times)] [extra cmake -D options]
# AOSR_BUILD_TIMES_DEV=0 builds only the default target (command 1's).
# Run on an idle machine: the times are wall times of each compiler process. ccache is bypassed (CCACHE_DISABLE)
# so that every file is really compiled.
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${1:-/tmp/aosr-build-times}
shift || true
rm -rf "$dir"
mkdir -p "$dir"
log="$dir/tu_times.log"
cat > "$dir/timecc.sh" <<'WRAP'
#!/usr/bin/env bash
# Runs a compiler command and appends "<CPU seconds (user + sys)> <wall seconds> <output file>" to $AOSR_TU_LOG.
# CPU time, not wall time, ranks the files: it does not grow when other work shares the machine.
out=""; prev=""
for a in "$@"; do [ "$prev" = "-o" ] && out="$a"; prev="$a"; done
t=$(mktemp)
/usr/bin/time -f "%U %S %e" -o "$t" "$@"; rc=$?
read -r u s e < "$t"; rm -f "$t"
echo "$(echo "$u + $s" | bc) $e $out" >> "$AOSR_TU_LOG"
exit $rc
WRAP
chmod +x "$dir/timecc.sh"
export AOSR_TU_LOG=$log CCACHE_DISABLE=1
generator=()
if command -v ninja > /dev/null; then generator=(-G Ninja); fi
jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B "$dir" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER_LAUNCHER="$dir/timecc.sh" "$@" \
  > "$dir/configure.log"
t0=$(date +%s)
/usr/bin/time -f "%e s wall, %U s user, %S s sys" -o "$dir/time1" cmake --build "$dir" -j"$jobs" > "$dir/build1.log"
t1=$(date +%s)
echo "default target (command 1's build): $(cat "$dir/time1")"
if [ "${AOSR_BUILD_TIMES_DEV:-1}" != 0 ]; then
  /usr/bin/time -f "%e s wall, %U s user, %S s sys" -o "$dir/time2" cmake --build "$dir" -j"$jobs" --target aosr_dev \
    > "$dir/build2.log"
  echo "aosr_dev on top (command 2's build): $(cat "$dir/time2")"
fi
echo "translation units: $(wc -l < "$log"), compiler CPU seconds summed: $(awk '{s += $1} END {printf "%.0f", s}' "$log")"
echo
echo "| CPU s | wall s | translation unit |"
echo "|---:|---:|---|"
sort -rn "$log" | head -${TOP:-30} | awk '{printf "| %.1f | %.1f | `%s` |\n", $1, $2, $3}'
echo
echo "by target (compiler CPU seconds summed):"
echo "| CPU s | files | target |"
echo "|---:|---:|---|"
sed -E 's#^([0-9.]+) [0-9.]+ .*CMakeFiles/([^/]+)\.dir/.*#\1 \2#' "$log" |
  awk '{s[$2] += $1; n[$2]++} END {for (t in s) printf "%.1f %d %s\n", s[t], n[t], t}' | sort -rn |
  head -${TOP:-30} | awk '{printf "| %.1f | %d | %s |\n", $1, $2, $3}'
