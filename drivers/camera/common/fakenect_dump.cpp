#include "drivers/camera/common/fakenect_dump.hpp"
