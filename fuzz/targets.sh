# shellcheck shell=bash
# What fuzz.sh and smoke.sh share (sourced, not run): the targets, the
# committed inputs and the dictionary of each, and the binaries' location.

# Every target in fuzz_targets/ (keep in step with Cargo.toml's [[bin]]s).
# shellcheck disable=SC2034 # used by the scripts that source this one
ALL_TARGETS=(rules_compile rules_run mesh_obj mesh_stl mesh_ply mesh_gltf mesh_glb info_report error_render)

# The folder of seeds/ and regressions/ a target reads (the two rule
# targets share theirs: same framing).
seeds_of() {
    case $1 in
        rules_compile | rules_run) echo rules ;;
        *) echo "$1" ;;
    esac
}

# The libFuzzer dictionary flag of a target (relative to fuzz/), if any.
dict_of() {
    case $1 in
        rules_compile | rules_run | error_render) echo "-dict=rules.dict" ;;
        mesh_obj | mesh_stl | mesh_ply | mesh_gltf | mesh_glb) echo "-dict=${1#mesh_}.dict" ;;
    esac
}

# Where `cargo fuzz build --target-dir DIR` puts the target binaries.
bin_dir() {
    local host
    host=$(rustc -vV | sed -n 's/^host: //p')
    echo "$1/$host/release"
}
