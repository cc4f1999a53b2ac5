# Shared by tests/fuzz.sh (CI) and bench/fuzz.sh (long runs). Source it from
# the repository root.

# The fuzz targets (tests/fuzz/fuzz_<target>.cpp), in the order they run.
FUZZ_TARGETS=(osm_xml osm_pbf sumo_net fcd vtypes gltf obj off ply mitsuba toml csv dataset_h5 sinr_h5 ns3_table_h5)

# The libFuzzer dictionary of a target (empty when it has none).
fuzz_dict() {
  case "$1" in
    osm_xml|sumo_net|fcd|vtypes|mitsuba) echo "tests/fuzz/dict/xml.dict" ;;
    toml) echo "tests/fuzz/dict/toml.dict" ;;
    *) echo "" ;;
  esac
}

# Succeeds when clang++ can build and link a libFuzzer program (clang plus
# libclang-rt-14-dev on Debian 12); prints why not otherwise.
fuzz_toolchain_ok() {
  if ! command -v clang++ >/dev/null 2>&1; then
    echo "fuzz: clang++ not found (Debian: apt-get install clang libclang-rt-14-dev)"; return 1
  fi
  local probe; probe=$(mktemp -d)
  printf 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }\n' > "$probe/p.cpp"
  if ! clang++ -fsanitize=fuzzer,address,undefined "$probe/p.cpp" -o "$probe/p" >/dev/null 2>&1; then
    rm -rf "$probe"
    echo "fuzz: clang++ cannot link -fsanitize=fuzzer (Debian: apt-get install libclang-rt-14-dev)"; return 1
  fi
  rm -rf "$probe"
}

# Configures and builds build-fuzz/ (incremental): the libraries with
# coverage + ASan + UBSan, the harnesses with libFuzzer's main.
fuzz_build() {
  export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1  # see setup.sh
  CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" -DRAYSWEEP_FUZZ=ON >/dev/null
  cmake --build build-fuzz --target fuzzers -j"$(nproc)"
}

# Sanitizer settings for the runs: any report is a finding (libFuzzer saves the input).
fuzz_env() {
  export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1"
  export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
  export LSAN_OPTIONS="suppressions=$PWD/tests/sanitize.supp:print_suppressions=0"
}
