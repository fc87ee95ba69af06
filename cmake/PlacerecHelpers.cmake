include(${CMAKE_CURRENT_LIST_DIR}/PlacerecCheckIncludes.cmake)

# One helper per kind of target. Every target gets the same warnings; PLACEREC_WERROR makes them errors.

function(placerec_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic
                         $<$<CXX_COMPILER_ID:GNU>:-Wshadow=local> -Wnon-virtual-dtor
                         -Wno-unused-parameter)
  if(PLACEREC_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# placerec_add_library(NAME SRCS a.cc ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
function(placerec_add_library name)
  cmake_parse_arguments(ARG "" "" "SRCS;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(${name} STATIC ${ARG_SRCS})
  target_include_directories(${name} PUBLIC ${PROJECT_SOURCE_DIR} ${PROJECT_BINARY_DIR})
  target_link_libraries(${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  set_target_properties(${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  placerec_set_warnings(${name})
  placerec_record_target(${name})
endfunction()

# placerec_add_executable(NAME SRCS a.cc ... [DEPS ...])
function(placerec_add_executable name)
  cmake_parse_arguments(ARG "" "" "SRCS;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SRCS})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bin)
  placerec_set_warnings(${name})
  placerec_record_target(${name})
endfunction()

# placerec_add_test(NAME SRCS a_test.cc ... [DEPS ...] [LABELS ...] [TIMEOUT seconds])
# A GoogleTest executable (main() from tests/test_main.cc: a temporary folder per process);
# each TEST becomes a CTest test.
function(placerec_add_test name)
  if(NOT PLACEREC_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "TIMEOUT" "SRCS;DEPS;LABELS" ${ARGN})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 600)
  endif()
  add_executable(${name} ${ARG_SRCS})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest placerec_test_main)
  target_compile_definitions(${name} PRIVATE
    PLACEREC_DEFAULT_DATA_DIR="${PLACEREC_DEFAULT_DATA_DIR}"
    PLACEREC_MODELS_DIR="${PLACEREC_MODELS_DIR}"
    PLACEREC_BINARY_DIR="${PROJECT_BINARY_DIR}")
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/tests)
  placerec_set_warnings(${name})
  placerec_record_target(${name})
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60
                       PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}")
endfunction()

# placerec_add_benchmark(NAME SRCS a.cc ... [DEPS ...]): a Google Benchmark executable (not a test).
function(placerec_add_benchmark name)
  cmake_parse_arguments(ARG "" "" "SRCS;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SRCS})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} benchmark::benchmark)
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bin)
  placerec_set_warnings(${name})
endfunction()
