// The bilinear model file .fbbm (algo/bilinear). Like the face model it carries a CRC-32 of
// bytes [16, end) at offset 12; each input is parsed as is and again with the CRC made right.
#include <cstring>
#include <vector>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/facemodel/face_model_format.hpp"
#include "tests/fuzz/fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto bytes = fb::fuzz::bytes(data, size);
  (void)fb::parse_bilinear_model(bytes);
  if (size < 64) return 0;
  std::vector<std::byte> sealed(bytes.begin(), bytes.end());
  const std::uint32_t crc = fb::fbfm::crc32(std::span<const std::byte>(sealed).subspan(16));
  std::memcpy(sealed.data() + 12, &crc, 4);
  auto model = fb::parse_bilinear_model(sealed);
  if (!model) return 0;
  std::vector<float> out(static_cast<std::size_t>(model->coordinate_count()));
  std::vector<float> w_id(static_cast<std::size_t>(model->id_knobs), 0.5f);
  std::vector<float> w_exp(static_cast<std::size_t>(model->exp_knobs), 0.5f);
  model->evaluate(w_id, w_exp, out);
  for (int i = 0; i < model->identity_count; ++i) (void)model->identity_row(i);
  for (int e = 0; e < model->expression_count; ++e) (void)model->expression_row(e);
  return 0;
}
