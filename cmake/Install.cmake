# Installs libgsd, its public headers, the CLI, a CMake package (find_package(gsd CONFIG) →
# gsd::gsd) and a pkg-config file (gsd.pc).
#
# The shared library needs nothing from its consumers but Eigen (the public headers use it).
# A static libgsd (GSD_SHARED=OFF) also needs the libraries it was built against; they are
# recorded by path for installed consumers, OpenMP found again by the package config.
include(CMakePackageConfigHelpers)

set(GSD_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/gsd)
set(gsd_static_deps "")
if(NOT GSD_SHARED)
  target_link_libraries(gsd INTERFACE
    $<INSTALL_INTERFACE:OpenMP::OpenMP_CXX ${CLP_LINK_LIBRARIES} ${CHOLMOD_LIBRARY}
                        ${STB_LINK_LIBRARIES} ${CMAKE_DL_LIBS}>)
  set(gsd_static_deps "find_dependency(OpenMP COMPONENTS CXX)")
endif()

install(TARGETS gsd EXPORT gsdTargets
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
# gsd/vulkan.hpp (the interop API) only exists in a build with Vulkan.
if(GSD_WITH_VULKAN)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/gsd DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
else()
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/gsd DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
          PATTERN vulkan.hpp EXCLUDE)
endif()
install(EXPORT gsdTargets NAMESPACE gsd:: FILE gsdTargets.cmake DESTINATION ${GSD_CMAKE_DIR})

file(CONFIGURE OUTPUT ${CMAKE_CURRENT_BINARY_DIR}/gsdConfig.cmake CONTENT
"# gsd's CMake package: find_package(gsd CONFIG) defines gsd::gsd.
include(CMakeFindDependencyMacro)
find_dependency(Eigen3 3.3 NO_MODULE)
@gsd_static_deps@
include(\${CMAKE_CURRENT_LIST_DIR}/gsdTargets.cmake)
" @ONLY)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/gsdConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/gsdConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/gsdConfigVersion.cmake
        DESTINATION ${GSD_CMAKE_DIR})

# pkg-config: `pkg-config --cflags --libs gsd` (add --static for a static libgsd).
set(gsd_pc_private "")
if(NOT GSD_SHARED)
  list(JOIN CLP_LINK_LIBRARIES " " clp_libs)
  set(gsd_pc_private "Libs.private: -fopenmp ${clp_libs} ${CHOLMOD_LIBRARY} ${STB_LINK_LIBRARIES} -ldl")
endif()
# The prefix is found from the file's own place, so `cmake --install --prefix P` anywhere works.
file(RELATIVE_PATH gsd_pc_to_prefix /${CMAKE_INSTALL_LIBDIR}/pkgconfig /)
file(CONFIGURE OUTPUT ${CMAKE_CURRENT_BINARY_DIR}/gsd.pc CONTENT
"prefix=\${pcfiledir}/${gsd_pc_to_prefix}
libdir=\${prefix}/${CMAKE_INSTALL_LIBDIR}
includedir=\${prefix}/${CMAKE_INSTALL_INCLUDEDIR}

Name: gsd
Description: ${PROJECT_DESCRIPTION}
Version: ${PROJECT_VERSION}
Requires: eigen3
Cflags: -I\${includedir}
Libs: -L\${libdir} -lgsd
${gsd_pc_private}
" @ONLY)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/gsd.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
