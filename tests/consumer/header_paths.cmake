# Every file the installed header cites (docs/*.md, examples/*.cpp, any a/b.h
# path) is installed too, under share/doc/skintune: the header is read where
# skintune's source tree is not.
#   cmake -DPREFIX=<install prefix> -DDOCDIR=<relative doc dir> -P header_paths.cmake
file(READ "${PREFIX}/include/skintune/skintune.h" header)
string(REGEX MATCHALL "[A-Za-z_]+/[A-Za-z_0-9./]+\\.(md|h|cpp|json)" cited "${header}")
list(REMOVE_DUPLICATES cited)
list(REMOVE_ITEM cited "skintune/skintune.h")
set(missing "")
foreach(path IN LISTS cited)
  if(NOT EXISTS "${PREFIX}/${DOCDIR}/${path}")
    list(APPEND missing "${path}")
  endif()
endforeach()
if(missing)
  message(FATAL_ERROR "the installed skintune.h cites files that are not installed: ${missing}")
endif()
list(LENGTH cited n)
message(STATUS "the installed header cites ${n} files, all installed: ${cited}")
