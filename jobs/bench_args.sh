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

# a / b of two parsed times, printed with `digits` decimals; stops the script (exit 1) when either
# is empty or not a positive number (a drifted log or table format would otherwise print a
# truncated row and exit 0: awk's division by zero fails inside a command substitution).
ratio() {  # ratio a b [digits]; a and b may carry blanks (table cells)
  local re='^[0-9]*\.?[0-9]+([eE][-+]?[0-9]+)?$' a=${1//[[:space:]]/} b=${2//[[:space:]]/}
  if ! [[ "$a" =~ $re && "$b" =~ $re ]] || ! awk -v a="$a" -v b="$b" 'BEGIN { exit !(a > 0 && b > 0) }'; then
    echo "$bench_script: could not read two times from the runs ('$1', '$2')" >&2
    exit 1
  fi
  awk -v a="$a" -v b="$b" -v d="${3:-2}" 'BEGIN { printf "%.*f", d, a / b }'
}

# median of the numbers on stdin, one per line (the mean of the middle two for an even count).
median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
