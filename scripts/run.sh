#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine: installs what is missing,
# configures and builds with the CMake presets, then runs one job.
#
#   bash scripts/run.sh demo [args]   the main job on its embedded default
#   bash scripts/run.sh test          the whole test suite (Release build)
#   bash scripts/run.sh sanitize      the whole test suite under ASan + UBSan
#   bash scripts/run.sh fuzz [SECONDS [SEED]]  each libFuzzer target (fuzz/) for SECONDS (60)
#                                     on a copy of its seed corpus, two at a time (clang),
#                                     with libFuzzer's SEED (1; 0 for a random one)
#   bash scripts/run.sh tsan          the thread-safety tests under ThreadSanitizer (clang)
#   bash scripts/run.sh bench [args]  the benchmark (pwcontact_bench, Google Benchmark's flags
#                                     and its own), then its summary from the JSON output
#                                     (bench/report.py summary)
#   bash scripts/run.sh screen-bench [args]  the screening benchmark (pwcontact_screen)
#   bash scripts/run.sh moves-bench [args]   trial moves, Monte Carlo sweeps, neighbour lists
#                                     and FCL (pwcontact_moves; installs libfcl-dev)
#   bash scripts/run.sh python-bench [args]  what the Python binding costs against the C++
#                                     calls (bench/python_overhead.py; --threads N)
#   bash scripts/run.sh trade [args]  the speed/accuracy trade (pwcontact_trade), labelled
#                                     with the commit measured, then its CSV, Markdown and
#                                     gnuplot plot from the JSON output (bench/report.py
#                                     trade: --csv=, --markdown=, --plot=, --no-plot, --label=
#                                     go to it, every other flag to pwcontact_trade); to
#                                     refresh the committed results: --csv=bench/results/trade.csv
#                                     --markdown=bench/results/trade.md --plot=bench/results/trade.png
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

job="${1:-}"
[ $# -gt 0 ] && shift
case "$job" in
  demo|test|sanitize|fuzz|tsan|bench|screen-bench|moves-bench|python-bench|trade) ;;
  *) echo "usage: bash scripts/run.sh demo|test|sanitize|fuzz|tsan|bench|screen-bench|moves-bench|python-bench|trade [args...]" >&2; exit 2 ;;
esac

# Debian packages the build needs (compiler, CMake, and every dependency).
packages=(g++ cmake make time libxsimd-dev libeigen3-dev libgtest-dev libgmock-dev
          libbenchmark-dev libboost-dev)
[ "$job" = trade ] && packages+=(gnuplot-nox)  # draws the trade's plot
[ "$job" = moves-bench ] && packages+=(libfcl-dev)  # the baseline of the trial moves
# The test job builds the screen over MPI ranks (pwcontact_mpi) and runs it
# under mpirun (OpenMPI), also from Python (mpi4py); the sanitizer, fuzz and
# tsan presets build without it.
[ "$job" = test ] && packages+=(libopenmpi-dev openmpi-bin python3-mpi4py)
# The scene-file tests also read back what they write with the gsd package.
case "$job" in test|sanitize) packages+=(python3-gsd) ;; esac
# The test suite checks the C++ layout against .clang-format with clang-format 14.
case "$job" in test|sanitize) packages+=(clang-format-14) ;; esac
# The release preset builds the Python module (pybind11, numpy) against
# /usr/bin/python3, and the tests run it with pytest.
case "$job" in sanitize|fuzz|tsan) ;;
  *) packages+=(pybind11-dev python3-dev python3-numpy python3-pytest python3-gsd) ;; esac
# libFuzzer and ThreadSanitizer come with clang; LLVM's OpenMP runtime is
# the one ThreadSanitizer understands.
case "$job" in fuzz|tsan) packages+=(clang-14 libclang-rt-14-dev libomp-14-dev) ;; esac
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing missing packages: ${missing[*]}" >&2
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

jobs="$(nproc)"
case "$job" in
  demo)
    cmake --preset release >/dev/null
    cmake --build --preset release -j "$jobs" --target pwcontact_cli
    exec build/release/src/pwcontact demo "$@" ;;
  test)
    cmake --preset release >/dev/null
    cmake --build --preset release -j "$jobs"
    exec ctest --preset release ;;
  sanitize)
    cmake --preset sanitize >/dev/null
    cmake --build --preset sanitize -j "$jobs"
    exec ctest --preset sanitize ;;
  fuzz)
    cmake --preset fuzz >/dev/null
    cmake --build --preset fuzz -j "$jobs"
    seconds="${1:-60}"
    # A fixed seed by default: the same inputs on every machine at the same
    # speed, so that a failure is reproducible with the same command; a seed
    # of 0 lets libFuzzer choose one (for longer runs that explore).
    seed="${2:-1}"
    work=build/fuzz/corpora
    targets=(number_table_fuzz contact_input_fuzz screen_input_fuzz options_fuzz kernels_fuzz)
    run_target() {  # a target on its own copy of the seed corpus, its log kept
      local target="$1"
      mkdir -p "$work/$target"
      cp -n fuzz/corpus/"$target"/* "$work/$target"/
      build/fuzz/fuzz/"$target" -seed="$seed" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
        -print_final_stats=1 -artifact_prefix="build/fuzz/$target-" "$work/$target" \
        > "build/fuzz/$target.log" 2>&1
    }
    failed=()
    for ((k = 0; k < ${#targets[@]}; k += 2)); do
      pids=()
      for target in "${targets[@]:k:2}"; do
        echo "fuzzing $target for $seconds s" >&2
        run_target "$target" & pids+=($!)
      done
      for ((p = 0; p < ${#pids[@]}; ++p)); do
        target="${targets[k + p]}"
        if wait "${pids[p]}"; then
          grep -E "^Done|stat::number_of_executed_units|cov:" "build/fuzz/$target.log" | tail -n 2 >&2
        else
          cat "build/fuzz/$target.log" >&2
          failed+=("$target")
        fi
      done
    done
    if [ ${#failed[@]} -gt 0 ]; then echo "fuzz targets failed: ${failed[*]}" >&2; exit 1; fi
    exit 0 ;;
  tsan)
    cmake --preset tsan >/dev/null
    cmake --build --preset tsan -j "$jobs" --target thread_safety_test
    exec ctest --preset tsan ;;
  bench)
    cmake --preset release >/dev/null
    cmake --build --preset release -j "$jobs" --target pwcontact_bench
    # The run's JSON (unless the caller names another file) is what the
    # summary is made from; after a JSON or CSV display the summary goes to
    # standard error, so that standard output stays machine-readable.
    json=build/release/bench/pwcontact_bench.json
    summary_to=1
    for a in "$@"; do
      case "$a" in
        --help) exec build/release/bench/pwcontact_bench --help ;;
        --benchmark_list_tests|--benchmark_list_tests=true) exec build/release/bench/pwcontact_bench "$@" ;;
        --benchmark_out=*) json="${a#--benchmark_out=}" ;;
        --benchmark_format=json|--benchmark_format=csv) summary_to=2 ;;
      esac
    done
    rm -f "$json"
    build/release/bench/pwcontact_bench "--benchmark_out=$json" --benchmark_out_format=json "$@"
    exec /usr/bin/python3 bench/report.py summary "$json" >&"$summary_to" ;;
  screen-bench)
    cmake --preset release >/dev/null
    cmake --build --preset release -j "$jobs" --target pwcontact_screen
    exec build/release/bench/pwcontact_screen "$@" ;;
  moves-bench)
    cmake --preset release >/dev/null
    cmake --build --preset release -j "$jobs" --target pwcontact_moves
    exec build/release/bench/pwcontact_moves "$@" ;;
  python-bench)
    cmake --preset release >/dev/null
    cmake --build --preset release -j "$jobs" --target _pwcontact
    PYTHONPATH=build/release/python exec /usr/bin/python3 bench/python_overhead.py "$@" ;;
  trade)
    cmake --preset release >/dev/null
    cmake --build --preset release -j "$jobs" --target pwcontact_trade
    label="$(git log -1 --format='commit %h of %cs' 2>/dev/null || echo 'not a git checkout')"
    git diff --quiet HEAD -- src include 2>/dev/null || label="$label, with uncommitted changes"
    # The report's flags go to bench/report.py, every other to pwcontact_trade
    # (with Google Benchmark's); the caller's come last and override the label.
    json=build/release/bench/trade/trade.json
    measure=()
    report=()
    for a in "$@"; do
      case "$a" in
        --help) exec build/release/bench/pwcontact_trade --help ;;
        --csv=*|--markdown=*|--plot=*|--no-plot|--label=*) report+=("$a") ;;
        --benchmark_out=*) json="${a#--benchmark_out=}"; measure+=("$a") ;;
        *) measure+=("$a") ;;
      esac
    done
    mkdir -p "$(dirname "$json")"
    rm -f "$json"
    build/release/bench/pwcontact_trade "--pwcontact_label=$label" "--benchmark_out=$json" \
      --benchmark_out_format=json "${measure[@]}"
    exec /usr/bin/python3 bench/report.py trade "$json" "${report[@]}" ;;
esac
