# The floors are one-way (docs/ARCHITECTURE.md): a folder's sources include
# the folders below it and never one above.
#
#   cmake -DSOURCE_DIR=<skintune's source> -DFLOORS=<lowest>,...,<highest> -P floors.cmake
#
# FLOORS is SKINTUNE_FLOORS of the top-level CMakeLists.txt, lowest first. A
# floor may be a sub-folder (tools/emit): a path belongs to the longest floor
# that holds it. Every C++ source and header under the floors (and under the
# folders of kIncludeRoots) is read, and each `#include "X/..."` fails the test,
# named by file and line, when X is a floor above the file's or no floor at all.
cmake_minimum_required(VERSION 3.22)
foreach(required SOURCE_DIR FLOORS)
  if(NOT DEFINED ${required})
    message(FATAL_ERROR "floors.cmake: -D${required}= is required")
  endif()
endforeach()
string(REPLACE "," ";" floors "${FLOORS}")

# Include roots that are not floors of their own: the kernel templates are the
# generator's (embedded into it), and `skintune/skintune.h` is the runtime's
# public header (runtime/include/skintune/).
set(kIncludeRoots templates=generator skintune=runtime)
set(kSourceGlobs *.h *.hpp *.cpp *.cc *.inc *.cu *.cuh)

# rank_<folder>: the floor's place from the bottom; name_<folder>: the floor
# a folder counts as (itself, or its include root's floor).
set(rank 0)
set(folders "")
foreach(floor IN LISTS floors)
  if(NOT IS_DIRECTORY "${SOURCE_DIR}/${floor}")
    message(FATAL_ERROR "floors.cmake: the floor ${floor} is not a folder of ${SOURCE_DIR}")
  endif()
  set("rank_${floor}" ${rank})
  set("name_${floor}" "${floor}")
  list(APPEND folders "${floor}")
  math(EXPR rank "${rank} + 1")
endforeach()
foreach(root IN LISTS kIncludeRoots)
  string(REPLACE "=" ";" pair "${root}")
  list(GET pair 0 folder)
  list(GET pair 1 floor)
  if(NOT DEFINED "rank_${floor}")
    continue()  # a tree without that floor (the test's own fixture)
  endif()
  set("rank_${folder}" "${rank_${floor}}")
  set("name_${folder}" "${floor}")
  list(APPEND folders "${folder}")
endforeach()

# The folder of `folders` that holds `path` (the longest), or "".
function(folder_of path out_var)
  set(best "")
  set(best_length 0)
  foreach(folder IN LISTS folders)
    string(LENGTH "${folder}/" length)
    string(SUBSTRING "${path}" 0 ${length} head)
    if(head STREQUAL "${folder}/" AND length GREATER best_length)
      set(best "${folder}")
      set(best_length ${length})
    endif()
  endforeach()
  set(${out_var} "${best}" PARENT_SCOPE)
endfunction()

# The line number of the first line of `file` that is `line`.
function(line_number_of file line out_var)
  file(READ "${SOURCE_DIR}/${file}" content)
  string(FIND "${content}" "${line}" at)
  string(SUBSTRING "${content}" 0 ${at} before)
  string(REGEX REPLACE "[^\n]" "" newlines "${before}")
  string(LENGTH "${newlines}" count)
  math(EXPR count "${count} + 1")
  set(${out_var} ${count} PARENT_SCOPE)
endfunction()

set(globs "")
foreach(folder IN LISTS folders)
  foreach(glob IN LISTS kSourceGlobs)
    list(APPEND globs "${SOURCE_DIR}/${folder}/${glob}")
  endforeach()
endforeach()
file(GLOB_RECURSE files RELATIVE "${SOURCE_DIR}" ${globs})
list(REMOVE_DUPLICATES files)

set(wrong "")
set(include_count 0)
set(floors_with_files "")
set(include_line "^[ \t]*#[ \t]*include[ \t]*\"([^\"]*/[^\"]*)\"")
foreach(file IN LISTS files)
  folder_of("${file}" from)
  set(from_floor "${name_${from}}")
  list(APPEND floors_with_files "${from_floor}")
  file(STRINGS "${SOURCE_DIR}/${file}" lines REGEX "${include_line}" ENCODING UTF-8)
  foreach(line IN LISTS lines)
    if(NOT line MATCHES "${include_line}")
      continue()
    endif()
    set(included "${CMAKE_MATCH_1}")
    math(EXPR include_count "${include_count} + 1")
    folder_of("${included}" to)
    if(to STREQUAL "")
      line_number_of("${file}" "${line}" number)
      list(APPEND wrong "${file}:${number}: `${line}`: ${included} is in no floor (${FLOORS})")
    elseif("${rank_${to}}" GREATER "${rank_${from}}")
      line_number_of("${file}" "${line}" number)
      list(APPEND wrong "${file}:${number}: `${line}`: ${from_floor} includes ${name_${to}}, a floor above it")
    endif()
  endforeach()
endforeach()

foreach(floor IN LISTS floors)
  if(NOT floor IN_LIST floors_with_files)
    list(APPEND wrong "${floor}: no C++ source or header found")
  endif()
endforeach()
if(wrong)
  list(JOIN wrong "\n  " text)
  message(FATAL_ERROR "includes that run upward (floors, lowest first: ${FLOORS}):\n  ${text}")
endif()
list(LENGTH files file_count)
message(STATUS "${file_count} files, ${include_count} includes of a folder: each of its own floor or one below (${FLOORS})")
