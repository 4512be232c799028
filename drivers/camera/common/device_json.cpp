#include "drivers/camera/common/device_json.hpp"
