# skintune_embed_kernels(TARGET <target> DB <winners-db.json> DEVICE <pattern>
#                        [LANG <lang>...] [JOINTS <n>] [HEADER <name.h>] [NAMESPACE <ns>])
#
# At build time, runs `skintune emit --db <DB> --device <pattern>` (the
# skintune::skintune command of this package) and adds the generated header
# to <target>: the winning kernels of the matching devices with their variant
# parameters, launch geometry and a packing helper, needing only the C++17
# standard library (no skintune library at run time). The header is
# regenerated when the database changes.
#
#   TARGET     the target that #includes the header (its include path gains the folder)
#   DB         winners database (`skintune tune` / `skintune db merge`); relative to
#              CMAKE_CURRENT_SOURCE_DIR
#   DEVICE     matched against each entry's device id, name, vendor and platform
#              (case-insensitive substring; "" takes every device)
#   LANG       opencl, cuda, glsl-compute, glsl-vertex (default: every language)
#   JOINTS     palette size the kernels are specialised for (default 77)
#   HEADER     header name (default skintune_kernels.h)
#   NAMESPACE  C++ namespace of the header (default skintune_kernels)
function(skintune_embed_kernels)
  cmake_parse_arguments(PARSE_ARGV 0 arg "" "TARGET;DB;DEVICE;JOINTS;HEADER;NAMESPACE" "LANG")
  if(arg_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "skintune_embed_kernels: unknown arguments: ${arg_UNPARSED_ARGUMENTS}")
  endif()
  foreach(required TARGET DB)
    if(NOT arg_${required})
      message(FATAL_ERROR "skintune_embed_kernels: ${required} is required")
    endif()
  endforeach()
  if(NOT DEFINED arg_DEVICE)
    message(FATAL_ERROR "skintune_embed_kernels: DEVICE is required (\"\" takes every device)")
  endif()
  if(NOT TARGET ${arg_TARGET})
    message(FATAL_ERROR "skintune_embed_kernels: '${arg_TARGET}' is not a target")
  endif()
  if(NOT TARGET skintune::skintune)
    message(FATAL_ERROR "skintune_embed_kernels: the skintune::skintune command is not imported (find_package(skintune))")
  endif()
  get_filename_component(db "${arg_DB}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
  if(NOT EXISTS "${db}")
    message(FATAL_ERROR "skintune_embed_kernels: winners database '${db}' does not exist")
  endif()
  if(NOT arg_HEADER)
    set(arg_HEADER skintune_kernels.h)
  endif()
  set(options --header "${arg_HEADER}")
  if(arg_NAMESPACE)
    list(APPEND options --namespace "${arg_NAMESPACE}")
  endif()
  if(arg_JOINTS)
    list(APPEND options --joints "${arg_JOINTS}")
  endif()
  foreach(lang IN LISTS arg_LANG)
    list(APPEND options --lang "${lang}")
  endforeach()
  set(out "${CMAKE_CURRENT_BINARY_DIR}/skintune_embedded/${arg_TARGET}")
  add_custom_command(
    OUTPUT "${out}/${arg_HEADER}"
    COMMAND skintune::skintune emit --db "${db}" --device "${arg_DEVICE}" --out "${out}" ${options}
    DEPENDS "${db}" "$<TARGET_FILE:skintune::skintune>"
    COMMENT "skintune: embedding the winning kernels of '${arg_DEVICE}' from ${arg_DB}"
    VERBATIM)
  target_sources(${arg_TARGET} PRIVATE "${out}/${arg_HEADER}")
  target_include_directories(${arg_TARGET} PRIVATE "${out}")
endfunction()
