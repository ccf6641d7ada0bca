# No function of the tuner is longer than a reader can hold at once
# (docs/ARCHITECTURE.md, "The tuner"): every function body in tuner/*.cpp is at
# most MAX_LINES lines, from the line of its opening brace to the line of its
# closing one.
#
#   cmake -DSOURCE_DIR=<skintune's source> [-DMAX_LINES=80] -P function_length.cmake
#       fails naming file:line and length of each function body over MAX_LINES
#       lines in tuner/*.cpp.
#   cmake -DSELF_TEST_DIR=<a scratch folder> -P function_length.cmake
#       checks the counter itself on a file it writes there, with functions of
#       MAX_LINES and MAX_LINES + 1 lines, a member function, braces in strings,
#       characters and comments: only the two long ones must be named.
#
# The counter reads braces, not C++: a brace opens a function body unless its
# line opens a namespace, a struct, a class or an enum; a body is reported when
# only such scopes enclose it (a lambda inside a function counts as part of
# that function). Strings, character literals and // comments are removed
# first; a block comment or a raw string literal, which a line-by-line reader
# cannot follow, fails the check naming its line.
cmake_minimum_required(VERSION 3.22)
if(NOT DEFINED MAX_LINES)
  set(MAX_LINES 80)
endif()

# Appends "<file>:<line>: a function body of <n> lines (at most <max>): <first line>"
# to `out_var` for each body over `max` lines in `file` (named `name` in messages).
function(long_functions file name max out_var)
  file(READ "${file}" content)
  # One list element per line: characters that CMake's lists treat specially
  # are replaced first (a backslash escape keeps its quote out of the way).
  string(REPLACE "\\\\" "BB" content "${content}")
  string(REPLACE "\\\"" "BQ" content "${content}")
  string(REPLACE "\\'" "BQ" content "${content}")
  string(REPLACE "\\" "B" content "${content}")
  string(REPLACE ";" "," content "${content}")
  string(REPLACE "[" "(" content "${content}")
  string(REPLACE "]" ")" content "${content}")
  string(REPLACE "\n" ";" lines "${content}")
  set(found "")
  set(stack "")  # per open brace: <line>:ns or <line>:f
  set(number 0)
  foreach(line IN LISTS lines)
    math(EXPR number "${number} + 1")
    set(code "${line}")
    string(REGEX REPLACE "\"[^\"]*\"" "\"\"" code "${code}")
    string(REGEX REPLACE "//.*$" "" code "${code}")
    string(REGEX REPLACE "/\\*.*\\*/" "" code "${code}")
    string(REGEX REPLACE "'[^']?[^']?'" "''" code "${code}")
    if(code MATCHES "/\\*" OR code MATCHES "R\"")
      message(FATAL_ERROR "${name}:${number}: a block comment or raw string across lines, which function_length.cmake cannot read")
    endif()
    string(REGEX REPLACE "[^{}]" "" braces "${code}")
    if(braces STREQUAL "")
      continue()
    endif()
    set(kind f)
    if(line MATCHES "namespace" OR line MATCHES "^[ \t]*(struct|class|enum)([ \t]|$)")
      set(kind ns)
    endif()
    string(LENGTH "${braces}" count)
    math(EXPR last "${count} - 1")
    foreach(i RANGE ${last})
      string(SUBSTRING "${braces}" ${i} 1 brace)
      if(brace STREQUAL "{")
        list(APPEND stack "${number}:${kind}")
        continue()
      endif()
      list(LENGTH stack depth)
      if(depth EQUAL 0)
        continue()
      endif()
      list(POP_BACK stack top)
      string(REPLACE ":" ";" top "${top}")
      list(GET top 0 start)
      list(GET top 1 top_kind)
      if(NOT top_kind STREQUAL "f" OR stack MATCHES ":f")
        continue()
      endif()
      math(EXPR length "${number} - ${start} + 1")
      if(length GREATER max)
        math(EXPR index "${start} - 1")
        list(GET lines ${index} first)
        string(STRIP "${first}" first)
        list(APPEND found "${name}:${start}: a function body of ${length} lines (at most ${max}): ${first}")
      endif()
    endforeach()
  endforeach()
  set(${out_var} "${found}" PARENT_SCOPE)
endfunction()

# A body of `n` lines opening with `head` (a signature ending in "{").
function(body_of head n out_var)
  set(text "${head}\n")
  math(EXPR inner "${n} - 2")
  foreach(i RANGE 1 ${inner})
    set(text "${text}  x += ${i};  // }\n")
  endforeach()
  set(${out_var} "${text}}\n" PARENT_SCOPE)
endfunction()

if(DEFINED SELF_TEST_DIR)
  math(EXPR over "${MAX_LINES} + 1")
  body_of("int AtTheLimit(int x) {" ${MAX_LINES} at_limit)
  body_of("int OverTheLimit(int x) {" ${over} over_limit)
  body_of("  int Member(int x) {" ${over} member)
  body_of("  auto inner = [&](int x) {" 40 lambda)
  set(sample "namespace sample {\n${at_limit}struct Holder {\n${member}};\n")
  string(APPEND sample "const char* kText = \"{ not a body\";\nconst char kBrace = '{';\n// a comment {\n")
  string(APPEND sample "int WithALambda(int x) {\n${lambda}  return inner(x);\n}\n${over_limit}}  // namespace sample\n")
  file(WRITE "${SELF_TEST_DIR}/function_length_sample.cpp" "${sample}")
  long_functions("${SELF_TEST_DIR}/function_length_sample.cpp" sample.cpp ${MAX_LINES} found)
  math(EXPR member_line "${MAX_LINES} + 3")
  math(EXPR over_line "${MAX_LINES} + ${over} + 50")
  set(expected
    "sample.cpp:${member_line}: a function body of ${over} lines (at most ${MAX_LINES}): int Member(int x) {"
    "sample.cpp:${over_line}: a function body of ${over} lines (at most ${MAX_LINES}): int OverTheLimit(int x) {")
  if(NOT found STREQUAL expected)
    string(REPLACE ";" "\n  " found "${found}")
    string(REPLACE ";" "\n  " expected "${expected}")
    message(FATAL_ERROR "function_length.cmake counted\n  ${found}\nexpected\n  ${expected}")
  endif()
  message(STATUS "function_length.cmake: the counter names exactly the two bodies over ${MAX_LINES} lines")
  return()
endif()

if(NOT DEFINED SOURCE_DIR)
  message(FATAL_ERROR "function_length.cmake: -DSOURCE_DIR= or -DSELF_TEST_DIR= is required")
endif()
file(GLOB files RELATIVE "${SOURCE_DIR}" "${SOURCE_DIR}/tuner/*.cpp")
list(LENGTH files file_count)
if(file_count LESS 5)
  message(FATAL_ERROR "function_length.cmake: found only ${file_count} files in ${SOURCE_DIR}/tuner")
endif()
set(all "")
foreach(file IN LISTS files)
  long_functions("${SOURCE_DIR}/${file}" "${file}" ${MAX_LINES} found)
  list(APPEND all ${found})
endforeach()
if(all)
  list(LENGTH all count)
  string(REPLACE ";" "\n  " all "${all}")
  message(FATAL_ERROR "${count} function(s) in tuner/ longer than ${MAX_LINES} lines (split them into functions "
                      "named for what each part does):\n  ${all}")
endif()
message(STATUS "function_length.cmake: ${file_count} files of tuner/, no function body over ${MAX_LINES} lines")
