#include "drivers/camera/recorder/recorder.hpp"
