#include "storage/asset_files.hpp"
// PLACEHOLDER
