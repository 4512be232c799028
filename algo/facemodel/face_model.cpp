#include "algo/facemodel/face_model.hpp"
// PLACEHOLDER: implemented by the face-model work.
