# cmake --install BUILD --prefix P: the facade library, its header under P/include/hnnstereo/,
# a relocatable CMake package (find_package(hnnstereo CONFIG), hnnstereo::hnnstereo) with a
# version file, and hnnstereo.pc. The kernels are embedded in the library. The per-folder static
# libraries the facade links are installed and exported too (hnnstereo::hnnstereo_stereo...), but
# their headers are not: a user includes <hnnstereo/hnnstereo.h> only.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(HNNSTEREO_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/hnnstereo)
install(TARGETS hnnstereo_api hnnstereo_api_core hnnstereo_vision hnnstereo_sensing hnnstereo_stereo
    hnnstereo_features hnnstereo_host hnnstereo_calib hnnstereo_common hnnstereo_kernels
    hnnstereo_opencl_config EXPORT hnnstereoTargets
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(FILES ${PROJECT_SOURCE_DIR}/api/hnnstereo/hnnstereo.h
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/hnnstereo)
install(EXPORT hnnstereoTargets NAMESPACE hnnstereo:: DESTINATION ${HNNSTEREO_CMAKE_DIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/hnnstereoConfig.cmake.in
  ${PROJECT_BINARY_DIR}/hnnstereoConfig.cmake INSTALL_DESTINATION ${HNNSTEREO_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/hnnstereoConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/hnnstereoConfig.cmake
  ${PROJECT_BINARY_DIR}/hnnstereoConfigVersion.cmake DESTINATION ${HNNSTEREO_CMAKE_DIR})
# A static facade needs the per-folder libraries after it on the link line.
set(HNNSTEREO_PC_PRIVATE_LIBS "")
if(NOT HNNSTEREO_SHARED_LIBRARY)
  set(HNNSTEREO_PC_PRIVATE_LIBS
      "-lhnnstereo_api_core -lhnnstereo_sensing -lhnnstereo_stereo -lhnnstereo_features -lhnnstereo_calib -lhnnstereo_host -lhnnstereo_kernels -lhnnstereo_common -pthread")
endif()
configure_file(${PROJECT_SOURCE_DIR}/cmake/hnnstereo.pc.in ${PROJECT_BINARY_DIR}/hnnstereo.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/hnnstereo.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
if(HNNSTEREO_BUILD_CLI)
  install(TARGETS hnnstereo RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
