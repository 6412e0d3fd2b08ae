# Shared compile settings for every hivox target. Applied per target: hivox sets no global flags.
function(hivox_target_options target)
  target_compile_features(${target} PUBLIC cxx_std_20)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF POSITION_INDEPENDENT_CODE ON)
  target_compile_options(${target} PRIVATE
    $<$<COMPILE_LANGUAGE:CXX>:-Wall -Wextra -Wpedantic -Wno-unknown-pragmas -Wno-missing-field-initializers>)
  if(CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    # Branchless masks (`a & b` on bools) are deliberate in the kernels; at -O1 (sanitizer
    # builds) clang says when it could not vectorize an `omp simd` loop, which is expected there.
    target_compile_options(${target} PRIVATE
      $<$<COMPILE_LANGUAGE:CXX>:-Wno-bitwise-instead-of-logical -Wno-pass-failed>)
  endif()
  if(HIVOX_NATIVE_ARCH)
    target_compile_options(${target} PRIVATE $<$<COMPILE_LANGUAGE:CXX>:-march=native>)
    # GCC 12 warns inside its own avx512fintrin.h (GCC bug 105593, fixed in 13).
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
      target_compile_options(${target} PRIVATE $<$<COMPILE_LANGUAGE:CXX>:-Wno-uninitialized>)
    endif()
  endif()
  if(HIVOX_SANITIZE STREQUAL "address")
    # UBSan without its object-size check: ASan finds the same reads and writes past an object
    # (more of them, with the allocation named), and with the check clang kept Eigen's small
    # accessors out of line, which made the suite's Eigen-heavy code (the synthetic scenes'
    # renderer, the tracker's solver) a third slower under the sanitizers.
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-sanitize=object-size
                                             -fno-omit-frame-pointer)
    target_link_options(${target} PUBLIC -fsanitize=address,undefined)
  elseif(HIVOX_SANITIZE STREQUAL "thread")
    target_compile_options(${target} PRIVATE -fsanitize=thread -fno-omit-frame-pointer)
    target_link_options(${target} PUBLIC -fsanitize=thread)
  elseif(NOT HIVOX_SANITIZE STREQUAL "")
    message(FATAL_ERROR "HIVOX_SANITIZE must be '', 'address' or 'thread', not '${HIVOX_SANITIZE}'")
  endif()
endfunction()

# hivox_add_module(NAME SOURCES ... [DEPS module...] [PUBLIC_LIBS ...] [PRIVATE_LIBS ...])
# Creates static library hivox_NAME (alias hivox::NAME). DEPS are other hivox modules; the
# module order in src/CMakeLists.txt enforces the one-way dependency direction. Every module's
# loops go through src/core/parallel.h, so each compiles with OpenMP privately: users of hivox
# link its runtime but never see its flags or headers.
function(hivox_add_module name)
  cmake_parse_arguments(M "" "" "SOURCES;DEPS;PUBLIC_LIBS;PRIVATE_LIBS" ${ARGN})
  set(target hivox_${name})
  add_library(${target} STATIC ${M_SOURCES})
  add_library(hivox::${name} ALIAS ${target})
  target_include_directories(${target}
    PUBLIC $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include> $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>
    PRIVATE ${PROJECT_SOURCE_DIR}/src)
  # Installed and exported as hivox::NAME (cmake/hivoxConfig.cmake.in).
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${name})
  set_property(GLOBAL APPEND PROPERTY HIVOX_MODULES ${target})
  foreach(dep IN LISTS M_DEPS)
    if(NOT TARGET hivox_${dep})
      message(FATAL_ERROR "hivox module '${name}' depends on '${dep}', which is not defined before it")
    endif()
    target_link_libraries(${target} PUBLIC hivox_${dep})
  endforeach()
  target_link_libraries(${target} PUBLIC ${M_PUBLIC_LIBS} PRIVATE ${M_PRIVATE_LIBS}
                                                                OpenMP::OpenMP_CXX)
  hivox_target_options(${target})
endfunction()
