#include "algo/sensor/kinect_calibration.hpp"
// PLACEHOLDER: implemented by the sensor-layer work.
