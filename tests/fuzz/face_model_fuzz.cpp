// The face model asset .fbfm (algo/facemodel). The file carries a CRC-32 over everything after
// the checksum field, so each input is parsed as is and once more with the checksum made right:
// otherwise nearly every mutation stops at the checksum.
#include <vector>

#include "algo/facemodel/face_model.hpp"
#include "algo/facemodel/face_model_format.hpp"
#include "tests/fuzz/fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto bytes = fb::fuzz::bytes(data, size);
  (void)fb::parse_face_model(bytes);
  if (size < fb::fbfm::kHeaderSize) return 0;
  std::vector<std::byte> sealed(bytes.begin(), bytes.end());
  fb::fbfm::reseal_checksum(sealed);
  auto model = fb::parse_face_model(sealed);
  if (!model) return 0;
  // A parsed model must be usable: evaluate touches every basis and the sizes behind them.
  std::vector<float> out(static_cast<std::size_t>(model->vertex_count) * 3);
  std::vector<float> id(static_cast<std::size_t>(model->identity_count), 0.5f);
  std::vector<float> ex(static_cast<std::size_t>(model->expression_count), 0.5f);
  model->evaluate(id, ex, out);
  return 0;
}
