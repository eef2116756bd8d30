# Installs the binaries (lgp, lgpd), the libraries and their public headers, and a CMake
# package (lgpConfig.cmake) so that a C++ user can `find_package(lgp)` and link lgp::lgp.
include(CMakePackageConfigHelpers)

set(LGP_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/lgp)
set(lgp_libraries lgp_core)
foreach(t lgp_emit lgp_datasets lgp_mpi)
  if(TARGET ${t})
    list(APPEND lgp_libraries ${t})
  endif()
endforeach()
install(TARGETS ${lgp_libraries} EXPORT lgpTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/lgp/include/lgp DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
if(TARGET lgp_emit)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/emit/include/lgp DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endif()
if(TARGET lgp_datasets)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/datasets/include/lgp
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endif()
foreach(t lgp lgpd)
  if(TARGET ${t})
    install(TARGETS ${t} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  endif()
endforeach()

install(EXPORT lgpTargets NAMESPACE lgp:: DESTINATION ${LGP_INSTALL_CMAKEDIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/lgpConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/lgpConfig.cmake
                              INSTALL_DESTINATION ${LGP_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/lgpConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/lgpConfig.cmake ${PROJECT_BINARY_DIR}/lgpConfigVersion.cmake
        DESTINATION ${LGP_INSTALL_CMAKEDIR})

# Everything `cmake --install` copies (scripts/lgp.sh install builds this, not the tests).
add_custom_target(lgp_installables)
foreach(t ${lgp_libraries} lgp lgpd lgp_gpu_worker _lgp)
  if(TARGET ${t})
    add_dependencies(lgp_installables ${t})
  endif()
endforeach()
