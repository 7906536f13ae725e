#!/usr/bin/env bash
# `nimbus compare` end to end, on small runs of the default cloud (16 x 16 x 12 cells, 2e4
# photons, a 32 x 20 image; well under a second each): the table; the JSON against the metrics
# recomputed from the HDF5 files (numpy); known answers: a run against itself gives 0, and
# against the same photons with every light and the background doubled 0.5 (1 the other way
# round) for the field and the image; --field and a reference without a standard error (no
# RMS z); a reference whose band is zero: its relative errors and RMS z "undefined" (JSON null
# with the reason, the absolute difference still given), exit 0; clear errors. At np ranks:
# rank 0 prints once, an error exits non-zero.
set -u
nimbus=$1 mpiexec=$2 np=$3
py=/usr/bin/python3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0
nim() { timeout 120 "$mpiexec" -n "$np" "$nimbus" "$@"; }
check() {  # check "<what>" <command...>: passes when the command succeeds
  local what=$1; shift
  if "$@"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: $what"; fi
}

# The lights and background are set explicitly so that the doubled run is exactly 2x (doubling
# is exact in floating point, and the photons are the same: same seed, same power ratios).
small=(--set "grid.n=[16,16,12]" --set "camera.resolution=[32,20]" --set model.montecarlo.photons=20000)
one=(--set "sun.irradiance=[1.0,0.9,0.8]" --set "sky.radiance=[0.03,0.05,0.09]" --set "background.color=[0.1,0.2,0.3]")
two=(--set "sun.irradiance=[2.0,1.8,1.6]" --set "sky.radiance=[0.06,0.1,0.18]" --set "background.color=[0.2,0.4,0.6]")
run() {  # run <name> args...
  local name=$1; shift
  nim run "$@" --out "$tmp/$name" > "$tmp/$name.log" 2>&1 || { echo "FAIL: nimbus run $name"; tail -5 "$tmp/$name.log"; exit 1; }
}
run a "${small[@]}" "${one[@]}" --set model.montecarlo.seed=1
run b "${small[@]}" "${one[@]}" --set model.montecarlo.seed=2
run a2 "${small[@]}" "${two[@]}" --set model.montecarlo.seed=1
run single "${small[@]}" "${one[@]}" --set 'model.name="single"'  # no standard errors
run nosun "${small[@]}" "${one[@]}" --set 'model.name="single"' --set sun.enabled=false  # no transmittance_sun
run a_exposure "${small[@]}" "${one[@]}" --set model.montecarlo.seed=1 --set render.exposure=2 --set render.step=0.25
A=$tmp/a/nimbus.h5 B=$tmp/b/nimbus.h5 A2=$tmp/a2/nimbus.h5 S=$tmp/single/nimbus.h5
IA=$tmp/a/nimbus.exr IA2=$tmp/a2/nimbus.exr
# A's output with band g's diffuse fluence and its standard error zero (as a band without
# light, or without scattering, gives): a reference on which g's relative errors are undefined.
Z=$tmp/zero_g.h5
"$py" - "$A" "$Z" <<'PY' || { echo "FAIL: making $Z"; exit 1; }
import shutil, sys
import h5py
shutil.copy(sys.argv[1], sys.argv[2])
with h5py.File(sys.argv[2], "r+") as f:
    for name in ("fluence_diffuse", "fluence_diffuse_stderr"):
        f[f"fields/{name}/g"][...] = 0
PY

# A's output with one NaN in band b's diffuse fluence (a failed run written by an older version):
# compare must refuse it, as run or reference, and not call it identical to itself.
N=$tmp/nan_b.h5
"$py" - "$A" "$N" <<'PY' || { echo "FAIL: making $N"; exit 1; }
import shutil, sys
import h5py
shutil.copy(sys.argv[1], sys.argv[2])
with h5py.File(sys.argv[2], "r+") as f:
    v = f["fields/fluence_diffuse/b"]
    x = v[...]
    x.flat[7] = float("nan")
    v[...] = x
PY
for pair in "$N $A" "$A $N" "$N $N"; do
  out=$(nim compare $pair 2>&1); code=$?
  check "non-finite field refused ($pair, exit $code)" [ $code -eq 1 ]
  check "non-finite field: the reason" bash -c 'echo "$1" | grep -q "nan_b.h5.: fields/fluence_diffuse/b has 1 non-finite value(s) (NaN or Inf)"' _ "$out"
done

# The table: one header (rank 0 only), a row per band, the image line.
out=$(nim compare "$A" "$B" --image-a "$IA" --image-b "$IA2" 2>&1); code=$?
echo "$out" > "$tmp/ab_table.txt"  # its RMS z note is checked against the JSON below
check "table exits 0 (exit $code)" [ $code -eq 0 ]
check "table header once" [ "$(echo "$out" | grep -c "fluence_diffuse of .* against reference")" -eq 1 ]
check "table columns" bash -c 'echo "$1" | grep -q "band *rel L2 *max rel *sum A/B *RMS z *cells"' _ "$out"
for band in r g b; do
  check "table row $band" bash -c 'echo "$1" | grep -Eq "^$2 +[0-9.]+e[-+][0-9]+ +[0-9.]+e[-+][0-9]+ +[0-9]\.[0-9]{4} +[0-9.]+ +[0-9]+$"' _ "$out" "$band"
done
check "table image line" bash -c 'echo "$1" | grep -Eq "^image: RMSE [0-9.]+e[-+][0-9]+, relative error [0-9.]+e[-+][0-9]+, brightness A/B [0-9]\.[0-9]{4} over 640 pixels$"' _ "$out"
# Without a standard error in the reference the RMS z column shows "-" (here another field:
# the unscattered fluence of the same light pass).
out=$(nim compare "$A" "$S" --field fluence_reduced 2>&1)
check "no stderr: RMS z '-'" bash -c 'echo "$1" | grep -Eq "^r +[0-9.]+e[-+][0-9]+ +[0-9.]+e[-+][0-9]+ +[0-9]\.[0-9]{4} +- +[0-9]+$"' _ "$out"

# transmittance_sun exists only for scenes with a sun: the error says so.
out=$(nim compare "$tmp/nosun/nimbus.h5" "$S" --field transmittance_sun 2>&1); code=$?
check "no sun: transmittance_sun refused (exit $code)" [ $code -eq 1 ]
check "no sun: the reason" bash -c 'echo "$1" | grep -q "has no fields/transmittance_sun: nimbus writes it only for scenes with a sun"' _ "$out"

# Against the zero band: exit 0, "undefined" in its row and a line saying why with the absolute
# difference; the other bands (A against itself) 0; no inf or nan anywhere.
out=$(nim compare "$A" "$Z" 2>&1); code=$?
check "zero reference: exits 0 (exit $code)" [ $code -eq 0 ]
check "zero reference: g undefined" bash -c 'echo "$1" | grep -Eq "^g +undefined +undefined +undefined +undefined +[0-9]+$"' _ "$out"
check "zero reference: r defined" bash -c 'echo "$1" | grep -Eq "^r +0\.0000e\+00 +0\.0000e\+00 +1\.0000 +0\.000 +[0-9]+$"' _ "$out"
check "zero reference: why, and |a - b|" bash -c 'echo "$1" | grep -Eq "^g: undefined \(the reference is zero on every cell compared\); \|a - b\| over the [0-9]+ cells: L2 [1-9][0-9.]*e[-+][0-9]+, max [1-9][0-9.]*e[-+][0-9]+$"' _ "$out"
check "zero reference: no inf or nan" bash -c '! echo "$1" | grep -Eqiw "inf|nan"' _ "$out"

# JSON: each comparison to a file, then checked in one Python run.
json() {  # json <name> compare-args...
  local name=$1; shift
  if nim compare "$@" --json > "$tmp/$name.json" 2> "$tmp/$name.err"; then pass=$((pass + 1))
  else fail=$((fail + 1)); echo "FAIL: compare --json $name exited non-zero"; fi
}
json ab "$A" "$B"
json aa "$A" "$A" --image-a "$IA" --image-b "$IA"
json a_a2 "$A" "$A2" --image-a "$IA" --image-b "$IA2"
json a2_a "$A2" "$A" --image-a "$IA2" --image-b "$IA"
json a_single "$A" "$S" --field fluence_reduced
json a_zero "$A" "$Z"
json zero_zero "$Z" "$Z"
json a_exposure "$A" "$tmp/a_exposure/nimbus.h5" --image-a "$IA" --image-b "$tmp/a_exposure/nimbus.exr"
results=$("$py" - "$tmp" <<'PY'
import json, sys
import h5py, numpy as np
tmp = sys.argv[1]
ok = bad = 0
def check(what, cond):
    global ok, bad
    if cond: ok += 1
    else: bad += 1; print("FAIL:", what)
def not_json(token):
    raise ValueError(f"not JSON: {token}")
def load(name):
    with open(f"{tmp}/{name}.json") as f:
        return json.load(f, parse_constant=not_json)  # fails the test if not JSON (NaN, Infinity)
def bands(r): return {b["band"]: b for b in r["bands"]}
def close(x, y, rel=1e-12): return abs(x - y) <= rel * max(abs(x), abs(y), 1e-300)

# A against B (two seeds): the metrics recomputed from the files, over cells with density.
ab = bands(load("ab"))
with h5py.File(f"{tmp}/a/nimbus.h5") as fa, h5py.File(f"{tmp}/b/nimbus.h5") as fb:
    rho = fb["fields/density"][...].astype(float)
    check("ab: bands r g b", sorted(ab) == ["b", "g", "r"])
    # in the scene's order (r, g, b), not the file's alphabetical one
    check("ab: bands in scene order", [b["band"] for b in load("ab")["bands"]] == ["r", "g", "b"])
    for band, j in ab.items():
        a = fa[f"fields/fluence_diffuse/{band}"][...].astype(float)[rho > 0]
        b = fb[f"fields/fluence_diffuse/{band}"][...].astype(float)[rho > 0]
        s = fb[f"fields/fluence_diffuse_stderr/{band}"][...].astype(float)[rho > 0]
        sa = fa[f"fields/fluence_diffuse_stderr/{band}"][...].astype(float)[rho > 0]
        check(f"ab {band}: cells", j["cells"] == int((rho > 0).sum()) > 0)
        check(f"ab {band}: rel_l2 {j['rel_l2']}", close(j["rel_l2"], np.linalg.norm(a - b) / np.linalg.norm(b)))
        check(f"ab {band}: max_rel {j['max_rel']}", close(j["max_rel"], np.abs(a - b).max() / np.abs(b).max()))
        check(f"ab {band}: sum_ratio {j['sum_ratio']}", close(j["sum_ratio"], a.sum() / b.sum(), 1e-9))
        # Two Monte Carlo runs: both standard errors count, over the cells where each is above 0
        # and below half its value; the table says so when that is not all of them.
        use = (s > 0) & (s < 0.5 * np.abs(b)) & (sa > 0) & (sa < 0.5 * np.abs(a))
        z = (a - b)[use] / np.sqrt(sa[use] ** 2 + s[use] ** 2)
        check(f"ab {band}: rms_z {j['rms_z']}", close(j["rms_z"], np.sqrt(np.mean(z * z))))
        nz, nc = int(use.sum()), int((rho > 0).sum())
        check(f"ab {band}: z_cells {j['z_cells']} = {nz}", j["z_cells"] == nz > 0)
        note = (f"{band}: RMS z over {nz} of the {nc} cells; on the others the standard error of A or B is 0 "
                "or at least half the value")
        check(f"ab {band}: the table notes the cells RMS z leaves out iff there are any ({nz} of {nc})",
              (note in open(f"{tmp}/ab_table.txt").read()) == (nz < nc))
        check(f"ab {band}: 0 < rel_l2 < 1", 0 < j["rel_l2"] < 1)
        check(f"ab {band}: abs_l2, max_abs", close(j["abs_l2"], np.linalg.norm(a - b)) and close(j["max_abs"], np.abs(a - b).max()))
        check(f"ab {band}: defined", "undefined" not in j)

# The stored scenes: A and B differ only in the Monte Carlo seed and A and `single` in the
# model, the same problem; A and 2A in the lights (and, with the images, in the background).
check("ab: same problem", load("ab")["same_problem"] is True)
check("a_single: same problem", load("a_single")["same_problem"] is True)
diff = load("a_a2")["problem_differences"]
check(f"a_a2: the lights and background differ ({diff})", diff == ["sun.irradiance", "sky.radiance", "background.color"])
check("a_exposure: the PNG's exposure and the ray caster's step are no other problem",
      load("a_exposure")["same_problem"] is True)

# A against itself: all zero.
aa = load("aa")
for band, j in bands(aa).items():
    check(f"aa {band}: zero", j["rel_l2"] == 0 and j["max_rel"] == 0 and j["rms_z"] == 0)
check("aa image: zero over 640 pixels", aa["image"] == {"rmse": 0.0, "rel_error": 0.0, "mean_ratio": 1.0, "pixels": 640})
for band, j in bands(aa).items():
    check(f"aa {band}: sum ratio 1", j["sum_ratio"] == 1.0)

# A against 2A: |a - 2a| / |2a| = 0.5; 2A against A: 1. RMS z is the same both ways (both
# standard errors count: z = -a / sqrt(s² + 4 s²) against a / sqrt(4 s² + s²)); the image
# RMSE is symmetric.
x, y = load("a_a2"), load("a2_a")
for band in "rgb":
    jx, jy = bands(x)[band], bands(y)[band]
    check(f"a_a2 {band}: 0.5", close(jx["rel_l2"], 0.5) and close(jx["max_rel"], 0.5))
    check(f"a2_a {band}: 1", close(jy["rel_l2"], 1.0) and close(jy["max_rel"], 1.0))
    check(f"a_a2, a2_a {band}: sum ratios 0.5, 2", close(jx["sum_ratio"], 0.5) and close(jy["sum_ratio"], 2.0))
    check(f"a_a2 {band}: rms_z symmetric", close(jx["rms_z"], jy["rms_z"]) and jy["rms_z"] > 0)
check(f"a_a2 image: rel_error 0.5 ({x['image']['rel_error']})", close(x["image"]["rel_error"], 0.5, 1e-6))
check(f"a2_a image: rel_error 1 ({y['image']['rel_error']})", close(y["image"]["rel_error"], 1.0, 1e-6))
check(f"image brightness 0.5 and 2 ({x['image']['mean_ratio']}, {y['image']['mean_ratio']})",
      close(x["image"]["mean_ratio"], 0.5, 1e-6) and close(y["image"]["mean_ratio"], 2.0, 1e-6))
check("image rmse symmetric, > 0", x["image"]["rmse"] > 0 and close(x["image"]["rmse"], y["image"]["rmse"]))
check("image pixels", x["image"]["pixels"] == 640)

# --field, and a reference without a standard error: no rms_z. Both runs made the same light
# pass, so the unscattered fluence agrees.
r = load("a_single")
check("a_single: field fluence_reduced", r["field"] == "fluence_reduced" and len(r["bands"]) == 3)
for band, j in bands(r).items():
    check(f"a_single {band}: no rms_z, equal", "rms_z" not in j and j["rel_l2"] < 1e-6)

# A against the zero band: g's relative errors and RMS z null with the reason, its absolute
# difference the norm of A's g; r and b (A against itself) 0. Z against itself: all 0.
z = bands(load("a_zero"))
with h5py.File(f"{tmp}/a/nimbus.h5") as fa:
    rho = fa["fields/density"][...].astype(float)
    a = fa["fields/fluence_diffuse/g"][...].astype(float)[rho > 0]
g = z["g"]
check(f"a_zero g: null {g}", g["rel_l2"] is None and g["max_rel"] is None and g["rms_z"] is None and g["sum_ratio"] is None)
check(f"a_zero g: reason {g.get('undefined')}", g.get("undefined") == "the reference is zero on every cell compared")
check(f"a_zero g: abs_l2 {g['abs_l2']}", g["abs_l2"] > 0 and close(g["abs_l2"], np.linalg.norm(a)))
check(f"a_zero g: max_abs {g['max_abs']}", close(g["max_abs"], np.abs(a).max()))
check("a_zero g: cells", g["cells"] == int((rho > 0).sum()))
for band in "rb":
    check(f"a_zero {band}: 0, defined", z[band]["rel_l2"] == 0 and z[band]["rms_z"] == 0 and "undefined" not in z[band])
for band, j in bands(load("zero_zero")).items():
    check(f"zero_zero {band}: 0, defined", j["rel_l2"] == 0 and j["max_rel"] == 0 and j["rms_z"] == 0 and "undefined" not in j)

# A file on another grid, for the error below.
with h5py.File(f"{tmp}/coarse.h5", "w") as f:
    f["fields/density"] = np.ones((6, 8, 8), dtype=np.float32)
    for band in "rgb":
        f[f"fields/fluence_diffuse/{band}"] = np.ones((6, 8, 8), dtype=np.float32)
print(ok, bad)
PY
)
echo "$results" | grep FAIL
read -r p f <<< "$(echo "$results" | tail -1)"
pass=$((pass + ${p:-0})) fail=$((fail + ${f:-1}))

# Errors: non-zero exit and one clear line, no internal error.
expect_error() {  # expect_error "<grep pattern>" compare-args...
  local pattern=$1; shift
  local out code
  out=$(nim compare "$@" 2>&1); code=$?
  if [ $code -ne 0 ] && [ $code -ne 124 ] && echo "$out" | grep -q -- "$pattern" && ! echo "$out" | grep -q "internal error"; then
    pass=$((pass + 1))
  else
    fail=$((fail + 1)); echo "FAIL (exit $code, want /$pattern/): nimbus compare $*"; echo "$out" | tail -3
  fi
}
expect_error "File does not exist: $tmp/missing.h5" "$A" "$tmp/missing.h5"
expect_error "File does not exist: $tmp/missing.exr" "$A" "$B" --image-a "$tmp/missing.exr" --image-b "$IA"
expect_error "nimbus: error: compare: give both --image-a and --image-b" "$A" "$B" --image-a "$IA"
expect_error "nimbus: error: .*the grids differ: A '$tmp/coarse.h5' has 8x8x6 cells, B '$A' has 16x16x12" "$tmp/coarse.h5" "$A"
echo "not HDF5" > "$tmp/text.h5"
expect_error "nimbus: error: cannot open HDF5 file '$tmp/text.h5': it is not an HDF5 file" "$A" "$tmp/text.h5"
head -c 2000 "$A" > "$tmp/truncated.h5"
expect_error "nimbus: error: cannot open HDF5 file '$tmp/truncated.h5': HDF5 refuses it: truncated or damaged" "$A" "$tmp/truncated.h5"
# A reference with band r only: A's g and b are not compared, and said so (they used to be
# dropped silently).
"$py" - "$A" "$tmp/r_only.h5" <<'PY' || { echo "FAIL: making r_only.h5"; exit 1; }
import shutil, sys
import h5py
shutil.copy(sys.argv[1], sys.argv[2])
with h5py.File(sys.argv[2], "r+") as f:
    for name in ("fluence_diffuse", "fluence_diffuse_stderr"):
        for band in "gb":
            del f[f"fields/{name}/{band}"]
PY
out=$(nim compare "$A" "$tmp/r_only.h5" 2>&1)
if [ $? -eq 0 ] && echo "$out" | grep -q "has bands \[\"g\",\"b\"\] that the reference .* lacks: not compared" &&
   echo "$out" | grep -Eq "^r +[0-9]"; then pass=$((pass + 1)); else
  fail=$((fail + 1)); echo "FAIL: bands of A missing from B not reported"; echo "$out" | tail -3; fi
# A against itself: all zeros, and a warning that this is by construction.
out=$(nim compare "$A" "$A" 2>&1)
if [ $? -eq 0 ] && echo "$out" | grep -q "A and B are the same file"; then pass=$((pass + 1)); else
  fail=$((fail + 1)); echo "FAIL: compare A A gives no same-file warning"; echo "$out" | tail -3; fi

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
