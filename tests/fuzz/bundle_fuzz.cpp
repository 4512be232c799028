// The session bundle a host receives from a booth (storage/bundle_import): the tar listing with
// its path checks, and the whole bundle (manifest, SHA-256 checks, session.json, captures). The
// first byte picks: 0 the listing, 1 the whole bundle as given, 2 a session.json wrapped into a
// bundle with a correct manifest (else almost every mutation stops at the checksum).
#include "storage/bundle_import.hpp"
#include "tests/common/bundle_writer.hpp"
#include "tests/fuzz/fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::span<const std::uint8_t> rest(data + 1, size - 1);
  switch (data[0] % 3) {
    case 0: {
      auto entries = fb::list_tar(rest);
      if (!entries) return 0;
      for (const auto& e : *entries) {
        fb::fuzz::require(e.offset + e.size <= rest.size(), "a listed file lies in the archive");
        fb::fuzz::require(
            !e.name.empty() && e.name.front() != '/' && e.name.find("..") == std::string::npos,
            "a listed name stays inside its folder");
      }
      return 0;
    }
    case 1:
      (void)fb::read_session_bundle(rest, "fuzz-booth", 0);
      return 0;
    default: {
      const std::string session(fb::fuzz::text(rest.data(), rest.size()));
      const std::string tar =
          fb::test::bundle({{"session-1/session.json", session, "session.json", session}});
      (void)fb::read_session_bundle(
          std::span(reinterpret_cast<const std::uint8_t*>(tar.data()), tar.size()), "fuzz-booth",
          0);
      return 0;
    }
  }
}
