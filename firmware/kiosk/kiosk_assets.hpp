// The kiosk page (index.html, kiosk.js, kiosk.css in this folder), embedded into faceboothd at
// build time so the device serves it without installed files (a generated .cpp, see
// CMakeLists.txt).
#pragma once

#include <string_view>

namespace fb {

std::string_view kiosk_html();
std::string_view kiosk_js();
std::string_view kiosk_css();

}  // namespace fb
