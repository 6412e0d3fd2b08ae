# `cmake --install`: the libraries, the public headers, the `hivox` program and a CMake package,
# so that other projects use hivox with
#   find_package(hivox REQUIRED)
#   target_link_libraries(app PRIVATE hivox::hivox)
# The modules are static libraries; what they use privately (OpenMP, spdlog, libpng, libjpeg,
# zstd, libzip, nlohmann-json, cpp-httplib, threads, Embree) is linked into the user's program but adds no compile flag and no
# header to it: hivoxConfig.cmake finds those packages only to link them.
include(CMakePackageConfigHelpers)

get_property(hivox_modules GLOBAL PROPERTY HIVOX_MODULES)
set(hivox_cmake_dir ${CMAKE_INSTALL_LIBDIR}/cmake/hivox)

install(TARGETS ${hivox_modules} hivox EXPORT hivoxTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS hivox_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/hivox DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT hivoxTargets NAMESPACE hivox:: DESTINATION ${hivox_cmake_dir})

configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/hivoxConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/hivoxConfig.cmake
                              INSTALL_DESTINATION ${hivox_cmake_dir})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/hivoxConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/hivoxConfig.cmake ${PROJECT_BINARY_DIR}/hivoxConfigVersion.cmake
        DESTINATION ${hivox_cmake_dir})
