// The export's 16-bit PGM depth maps (storage/export/png_file: encode_pgm16, once the daemon's
// own copy in record_files.hpp): the standard P5 layout with big-endian samples, checked
// against a real outside reader (OpenCV's imdecode).
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "storage/export/png_file.hpp"

namespace fb {
namespace {

TEST(ImageFiles, Pgm16IsStandardBigEndianP5) {
  DepthImage d;
  d.resize(3, 2);
  d.pixels = {0x03c6, 0x07ff, 0, 700, 65535, 1};
  const std::string pgm = encode_pgm16(d);
  const std::string header = "P5\n3 2\n65535\n";
  ASSERT_EQ(pgm.size(), header.size() + 12);
  EXPECT_EQ(pgm.substr(0, header.size()), header);
  EXPECT_EQ(static_cast<unsigned char>(pgm[header.size()]), 0x03);  // most significant first
  EXPECT_EQ(static_cast<unsigned char>(pgm[header.size() + 1]), 0xc6);

  const std::vector<unsigned char> bytes(pgm.begin(), pgm.end());
  const cv::Mat read = cv::imdecode(bytes, cv::IMREAD_ANYDEPTH);
  ASSERT_FALSE(read.empty());
  ASSERT_EQ(read.type(), CV_16UC1);
  ASSERT_EQ(read.cols, 3);
  ASSERT_EQ(read.rows, 2);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x)
      EXPECT_EQ(read.at<std::uint16_t>(y, x), d.at(x, y)) << x << "," << y;
}

}  // namespace
}  // namespace fb
