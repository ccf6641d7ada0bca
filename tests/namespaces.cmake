# The public namespace holds the public API and nothing else (docs/ARCHITECTURE.md,
# "Where internals live"): the library's own code lives in skintune::internal.
#
#   cmake -DSOURCE_DIR=<skintune's source> -DFLOORS=<floor>,... -P namespaces.cmake
#       every C++ file (and the CMake scripts that generate C++) opens
#       `namespace skintune::internal` and never `namespace skintune` itself or
#       another namespace under it, except the files of kPublicApiFiles below;
#       each of those does open `namespace skintune`.
#   cmake -DSOURCE_DIR=<...> -DNM=<nm> -DSHARED=<libskintune.so> -DLIBRARIES=<a;b;...> -P namespaces.cmake
#       the other way: the public names are the top-level names skintune.h
#       declares; libskintune.so exports only those, and no symbol of the
#       libraries (LIBRARIES: archives, executables) names anything under
#       skintune:: other than those and `internal`. This catches a helper
#       that a public-API file defines in `namespace skintune` by mistake.
cmake_minimum_required(VERSION 3.22)
foreach(required SOURCE_DIR)
  if(NOT DEFINED ${required})
    message(FATAL_ERROR "namespaces.cmake: -D${required}= is required")
  endif()
endforeach()

# The files that define the public API's functions and members (which C++
# requires in `namespace skintune`): the header, the Impl structs of its
# classes, and the definitions. Everything else they need lives in
# skintune::internal; these files use it through `using namespace internal;`.
set(kPublicApiFiles
  runtime/include/skintune/skintune.h
  runtime/device.h                        # Device::Impl
  runtime/skinner.h                       # Skinner::Impl
  runtime/selection.h                     # WinnersDb::Impl
  runtime/device.cpp                      # Device
  runtime/skinner.cpp                     # Skinner
  runtime/api_winners.cpp                 # WinnersDb, Selection::Find, BackendName, MatchLevelName, SceneShapeName
  runtime/api_model.cpp                   # Model
  runtime/backends/opencl/opencl_backend.cpp  # Device::FromOpenCl, Device::OpenClForCurrentGl
  runtime/backends/cuda/cuda_backend.cpp      # Device::FromCuda
  runtime/backends/gl/gl_backend.cpp          # Device::FromCurrentGl
  runtime/backends/vulkan/vulkan_backend.cpp  # Device::FromVulkan
)
# The folders read: the floors (FLOORS, the top-level CMakeLists.txt's SKINTUNE_FLOORS)
# and the folders that are no floor.
set(kOtherSourceFolders tests bench examples templates cmake)
set(kSourceGlobs *.h *.hpp *.cpp *.cc *.cu *.cuh *.inc *.cmake *.in)

# ---------------------------------------------------------------- the sources
if(NOT DEFINED NM)
if(NOT DEFINED FLOORS)
  message(FATAL_ERROR "namespaces.cmake: -DFLOORS= is required to read the sources")
endif()
string(REPLACE "," ";" floors "${FLOORS}")
set(globs "")
foreach(folder IN LISTS floors kOtherSourceFolders)
  foreach(glob IN LISTS kSourceGlobs)
    list(APPEND globs "${SOURCE_DIR}/${folder}/${glob}")
  endforeach()
endforeach()
file(GLOB_RECURSE files RELATIVE "${SOURCE_DIR}" ${globs})
list(REMOVE_DUPLICATES files)  # tools/ holds the floors tools/emit and tools/experiments
list(LENGTH files file_count)
if(file_count LESS 100)
  message(FATAL_ERROR "namespaces.cmake: found only ${file_count} source files under ${SOURCE_DIR}")
endif()

# The opening of a namespace named skintune or under it, at the start of a line
# (also after whitespace): `namespace skintune {`, `namespace skintune::x::y {`.
set(opening "^[ \t]*namespace[ \t]+skintune(::[A-Za-z_0-9:]+)?[ \t]*\\{")
set(wrong "")
set(public_seen "")
foreach(file IN LISTS files)
  file(STRINGS "${SOURCE_DIR}/${file}" lines REGEX "namespace[ \t]+skintune")
  list(FIND kPublicApiFiles "${file}" public_index)
  foreach(line IN LISTS lines)
    if(NOT line MATCHES "${opening}")
      continue()
    endif()
    set(nested "${CMAKE_MATCH_1}")
    if(nested STREQUAL "")
      if(public_index EQUAL -1)
        list(APPEND wrong "${file}: `${line}` (internals belong in skintune::internal)")
      else()
        list(APPEND public_seen "${file}")
      endif()
    elseif(NOT nested MATCHES "^::internal(::|$)")
      list(APPEND wrong "${file}: `${line}` (a namespace under skintune but outside skintune::internal)")
    endif()
  endforeach()
endforeach()
foreach(file IN LISTS kPublicApiFiles)
  if(NOT file IN_LIST public_seen)
    list(APPEND wrong "${file}: listed in kPublicApiFiles (tests/namespaces.cmake) but opens no `namespace skintune`")
  endif()
endforeach()
if(wrong)
  list(JOIN wrong "\n  " text)
  message(FATAL_ERROR "declarations outside skintune::internal:\n  ${text}")
endif()
list(LENGTH kPublicApiFiles public_count)
message(STATUS "${file_count} files: ${public_count} public-API files open `namespace skintune`, the others only skintune::internal")
return()
endif()

# ---------------------------------------------------------------- the symbols
# The public names: the top-level declarations of skintune.h (classes, structs,
# enums, functions, constants), outside its `namespace internal` block.
file(READ "${SOURCE_DIR}/runtime/include/skintune/skintune.h" header)
string(REGEX REPLACE "\nnamespace internal {[^}]*}" "" header "${header}")
string(REGEX MATCHALL "\n(class|struct|enum class) [A-Za-z_0-9]+|\n[A-Za-z_][^\n(;=]* \\**[A-Za-z_0-9]+\\(|\ninline constexpr [^\n=]* [A-Za-z_0-9]+ ="
  declarations "${header}")
set(public "")
foreach(d IN LISTS declarations)
  string(REGEX MATCH "([A-Za-z_0-9]+) *[(=]?$" _ "${d}")
  list(APPEND public "${CMAKE_MATCH_1}")
endforeach()
list(REMOVE_DUPLICATES public)
foreach(expected Skinner Device WinnersDb Selection Model Status Result BackendName)
  if(NOT expected IN_LIST public)
    message(FATAL_ERROR "namespaces.cmake: did not find `${expected}` among skintune.h's names: ${public}")
  endif()
endforeach()
list(JOIN public "|" public_alternatives)
message(STATUS "skintune.h declares: ${public}")

# The output of `nm ARGS...`, each symbol on its line, address and type cut off.
function(symbols_of out_var)
  execute_process(COMMAND "${NM}" ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${NM} ${ARGN} failed (${rc}): ${err}")
  endif()
  string(REGEX REPLACE "(^|\n)[0-9a-fA-F ]*[A-Za-z] " "\\1" out "${out}")
  set(${out_var} "${out}" PARENT_SCOPE)
endfunction()

set(wrong "")

# libskintune.so's dynamic symbols: public members and functions only (not
# their Impl structs').
symbols_of(exported -DC --defined-only "${SHARED}")
string(REPLACE ";" "," exported "${exported}")  # a list of lines
string(REPLACE "\n" ";" exported "${exported}")
set(count 0)
foreach(symbol IN LISTS exported)
  if(symbol STREQUAL "" OR symbol MATCHES "^(_init|_fini|_edata|_end|__bss_start)$")
    continue()
  endif()
  math(EXPR count "${count} + 1")
  if(NOT symbol MATCHES "^(typeinfo for |typeinfo name for |vtable for )?skintune::(${public_alternatives})[:(<]"
     OR symbol MATCHES "skintune::internal|::Impl[:(]")
    list(APPEND wrong "${SHARED} exports a non-public symbol: ${symbol}")
  endif()
endforeach()
if(count EQUAL 0)
  message(FATAL_ERROR "${NM} found no exported symbol in ${SHARED}")
endif()

# Every skintune::X that a symbol defined in the libraries names: X is public
# or `internal` (`skintune::(anonymous namespace)` is neither).
foreach(library IN LISTS LIBRARIES)
  symbols_of(symbols -C --defined-only "${library}")
  string(REGEX MATCHALL "skintune::(\\(anonymous namespace\\)|[A-Za-z_0-9]+)" names "${symbols}")
  list(REMOVE_DUPLICATES names)
  foreach(name IN LISTS names)
    if(NOT name MATCHES "^skintune::(internal|${public_alternatives})$")
      string(REGEX REPLACE "([()])" "\\\\\\1" pattern "${name}")
      string(REGEX MATCH "[^\n]*${pattern}[^\n]*" symbol "${symbols}")
      list(APPEND wrong "${library}: ${name} in `${symbol}`")
    endif()
  endforeach()
endforeach()

if(wrong)
  list(JOIN wrong "\n  " text)
  message(FATAL_ERROR "symbols naming skintune:: things that are neither public nor internal:\n  ${text}")
endif()
message(STATUS "${SHARED} exports ${count} symbols, all public; the libraries name no skintune:: other than the public names and internal")
