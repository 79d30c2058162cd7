# Helpers modelled on COLMAP's COLMAP_ADD_LIBRARY / COLMAP_ADD_TEST: one library per core/
# folder, tests registered one by one beside their code, named "<folder>/<test>" in ctest.

# The repository root: include paths are relative to it ("core/util/status.h").
get_filename_component(RECONDUIT_ROOT "${CMAKE_CURRENT_LIST_DIR}/.." ABSOLUTE)

# Compile options every Reconduit target gets.
function(reconduit_set_target_options target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wno-missing-field-initializers)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    # GCC 12 reports false -Wrestrict positives inside libstdc++'s std::string operator+ at -O3
    # (GCC bug 105329); nothing in our code can trigger the real problem it looks for.
    target_compile_options(${target} PRIVATE -Wno-restrict)
  endif()
  if(RECONDUIT_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(RECONDUIT_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-omit-frame-pointer
                                             -fno-sanitize-recover=undefined)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined)
  endif()
  if(RECONDUIT_FUZZ)
    # Coverage for libFuzzer in every library a fuzz target links; the targets themselves add
    # -fsanitize=fuzzer at link time (fuzz/CMakeLists.txt).
    target_compile_options(${target} PRIVATE -fsanitize=fuzzer-no-link,address,undefined
                                             -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined)
  endif()
endfunction()

# reconduit_add_library(NAME util SRCS a.cc b.cc PUBLIC_LINK_LIBS ... PRIVATE_LINK_LIBS ...)
# creates target reconduit_<NAME> (an INTERFACE library when SRCS is empty).
function(reconduit_add_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;PUBLIC_LINK_LIBS;PRIVATE_LINK_LIBS" ${ARGN})
  set(target reconduit_${ARG_NAME})
  if(ARG_SRCS)
    add_library(${target} STATIC ${ARG_SRCS})
    target_include_directories(${target} PUBLIC ${RECONDUIT_ROOT})
    target_link_libraries(${target} PUBLIC ${ARG_PUBLIC_LINK_LIBS} PRIVATE ${ARG_PRIVATE_LINK_LIBS})
    reconduit_set_target_options(${target})
  else()
    add_library(${target} INTERFACE)
    target_include_directories(${target} INTERFACE ${RECONDUIT_ROOT})
    target_link_libraries(${target} INTERFACE ${ARG_PUBLIC_LINK_LIBS})
  endif()
endfunction()

# reconduit_add_test(NAME camera_test SRCS camera_test.cc LINK_LIBS reconduit_geometry
#                    [LABELS unit] [FOLDER geometry])
# The ctest name is "<FOLDER>/<NAME>"; FOLDER defaults to the current source folder's name.
# Tests run with the repository root as working directory, so ../shared/datasets resolves
# the same way in every build tree.
function(reconduit_add_test)
  if(NOT RECONDUIT_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "NAME;FOLDER" "SRCS;LINK_LIBS;LABELS" ${ARGN})
  if(NOT ARG_FOLDER)
    get_filename_component(ARG_FOLDER ${CMAKE_CURRENT_SOURCE_DIR} NAME)
  endif()
  if(NOT ARG_LABELS)
    set(ARG_LABELS unit)
  endif()
  set(target ${ARG_FOLDER}_${ARG_NAME})
  # Unit tests of the folders in RECONDUIT_SANITIZE_FOLDERS also carry the label "sanitize" and
  # are what the target reconduit_sanitize_tests builds (see the top-level CMakeLists.txt).
  if("unit" IN_LIST ARG_LABELS AND ARG_FOLDER IN_LIST RECONDUIT_SANITIZE_FOLDERS)
    list(APPEND ARG_LABELS sanitize)
  endif()
  add_executable(${target} ${ARG_SRCS})
  if("sanitize" IN_LIST ARG_LABELS)
    add_dependencies(reconduit_sanitize_tests ${target})
  endif()
  target_link_libraries(${target} PRIVATE ${ARG_LINK_LIBS} GTest::gmock GTest::gtest_main)
  reconduit_set_target_options(${target})
  add_test(NAME ${ARG_FOLDER}/${ARG_NAME} COMMAND ${target})
  set_tests_properties(${ARG_FOLDER}/${ARG_NAME} PROPERTIES
    LABELS "${ARG_LABELS}" WORKING_DIRECTORY ${RECONDUIT_ROOT}
    ENVIRONMENT "RECONDUIT_SOURCE_DIR=${RECONDUIT_ROOT}")
endfunction()
