# .deb packaging (CPack DEB) for the device: the daemon, the host tool, the systemd unit, the
# udev rules, the default config, the data (face model, guide expressions) and the synthetic
# camera module (lib/facebooth/cameras/fb_camera_synthetic.so: the default config's demo camera
# and the kiosk's guide pictures). The laboratory's facebooth-lab has no install rule and is
# not in the package (sim/README.md). Included from
# firmware/daemon/CMakeLists.txt. Build with:  cpack --config <build>/CPackConfig.cmake -G DEB
# (amd64 natively; arm64 from the cross build, see scripts/cross-build).
set(_board ${PROJECT_SOURCE_DIR}/board)
install(FILES ${_board}/faceboothd.service DESTINATION lib/systemd/system)
install(FILES ${_board}/99-facebooth-kinect.rules ${_board}/60-facebooth-gpio.rules
  DESTINATION lib/udev/rules.d)
install(FILES ${_board}/faceboothd.toml DESTINATION /etc/facebooth)
install(FILES ${FB_DATA_DIR}/guide_expressions.json DESTINATION share/facebooth OPTIONAL)

set(CPACK_PACKAGE_NAME facebooth)
set(CPACK_PACKAGE_VENDOR "facebooth")
set(CPACK_PACKAGE_CONTACT "facebooth maintainers <facebooth@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "Kinect v1 face-capture appliance: faceboothd daemon and facebooth host tool")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_STRIP_FILES ON)  # RelWithDebInfo binaries carry ~200 MB of debug info
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
if(NOT CPACK_DEBIAN_PACKAGE_ARCHITECTURE)
  execute_process(COMMAND dpkg --print-architecture OUTPUT_VARIABLE CPACK_DEBIAN_PACKAGE_ARCHITECTURE
    OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
endif()
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA ${_board}/debian/postinst ${_board}/debian/prerm
  ${_board}/debian/conffiles)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_GENERATOR DEB)
include(CPack)
