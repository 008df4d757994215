# Compiles GLSL compute shaders to SPIR-V at build time and embeds them: each shader becomes a generated
# header `<name>_spv.h` declaring `const uint32_t <name>_spv[]`. --depfile makes edits to included headers
# (shaders/shared/*.h) rebuild the shaders that use them.
function(refract_add_shaders target)
  set(out_dir "${CMAKE_CURRENT_BINARY_DIR}/spirv")
  file(MAKE_DIRECTORY "${out_dir}")
  set(outputs "")
  foreach(src IN LISTS ARGN)
    get_filename_component(name "${src}" NAME_WE)
    set(abs "${CMAKE_CURRENT_SOURCE_DIR}/${src}")
    set(out "${out_dir}/${name}_spv.h")
    add_custom_command(
      OUTPUT "${out}"
      COMMAND "${GLSLANG_VALIDATOR}" -V --target-env vulkan1.2 -Os
              -I${CMAKE_CURRENT_SOURCE_DIR}/shared
              --depfile "${out}.d" --vn "${name}_spv" -o "${out}" "${abs}"
      MAIN_DEPENDENCY "${abs}"
      DEPFILE "${out}.d"
      COMMENT "glslang: ${src}"
      VERBATIM)
    list(APPEND outputs "${out}")
  endforeach()
  add_custom_target(${target}_spirv DEPENDS ${outputs})
  add_library(${target} INTERFACE)
  add_dependencies(${target} ${target}_spirv)
  target_include_directories(${target} INTERFACE "${out_dir}" "${CMAKE_CURRENT_SOURCE_DIR}/shared")
endfunction()
