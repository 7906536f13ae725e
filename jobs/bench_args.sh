# Sourced by the benchmark scripts: checks of their arguments that name the bad one and stop
# before anything runs (a size of "abc" used to reach the binaries as 0 and abort there).
bench_script=$(basename "$0")

# need_count <what> <value>: a whole number >= 1.
need_count() {
  [[ "$2" =~ ^[1-9][0-9]*$ ]] || { echo "$bench_script: $1 must be a whole number >= 1, not '$2'" >&2; exit 1; }
}

# need_whole <what> <value>: a whole number >= 0.
need_whole() {
  [[ "$2" =~ ^[0-9]+$ ]] || { echo "$bench_script: $1 must be a whole number >= 0, not '$2'" >&2; exit 1; }
}

# need_binary <path> <cmake target> <build dir>: an executable, or how to build it.
need_binary() {
  [ -x "$1" ] || {
    echo "$bench_script: missing $1: cmake --build $3 --target $2 (bash jobs/build.sh makes build/)" >&2
    exit 1
  }
}
