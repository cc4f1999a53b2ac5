#include "pipeline/provenance.hpp"

#include <openssl/crypto.h>
#include <openssl/evp.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>

#include "pipeline/version.hpp"

namespace raysweep::pipeline {

namespace {

// SHA-256 needs none of the system's OpenSSL configuration (openssl.cnf:
// providers, FIPS modes): not reading it saves every command about a
// millisecond, and hashes cannot depend on it.
const EVP_MD* sha256() {
  static const EVP_MD* md = [] {
    OPENSSL_init_crypto(OPENSSL_INIT_NO_LOAD_CONFIG, nullptr);
    return EVP_sha256();
  }();
  return md;
}

std::string hex(const unsigned char* digest, unsigned int len) {
  static const char* digits = "0123456789abcdef";
  std::string out;
  for (unsigned int i = 0; i < len; ++i) {
    out.push_back(digits[digest[i] >> 4]);
    out.push_back(digits[digest[i] & 15]);
  }
  return out;
}

}  // namespace

std::string sha256_file(const std::string& path) {
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), std::fclose);
  if (!f) throw std::runtime_error(path + ": cannot open for hashing");
  std::unique_ptr<EVP_MD_CTX, void (*)(EVP_MD_CTX*)> ctx(EVP_MD_CTX_new(), EVP_MD_CTX_free);
  EVP_DigestInit_ex(ctx.get(), sha256(), nullptr);
  std::vector<unsigned char> buf(1 << 16);
  std::size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), f.get())) > 0) EVP_DigestUpdate(ctx.get(), buf.data(), n);
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_DigestFinal_ex(ctx.get(), digest, &len);
  return hex(digest, len);
}

std::string sha256_text(const std::string& text) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_Digest(text.data(), text.size(), digest, &len, sha256(), nullptr);
  return hex(digest, len);
}

nlohmann::json provenance(const std::string& stage, const std::vector<InputFile>& inputs,
                          const nlohmann::json& config, const std::vector<std::string>& argv) {
  nlohmann::json in = nlohmann::json::array();
  for (const auto& f : inputs) {
    in.push_back({{"role", f.role},
                  {"path", f.path},
                  {"bytes", std::filesystem::file_size(f.path)},
                  {"sha256", sha256_file(f.path)}});
  }
  return {{"tool", "raysweep"},
          {"version", kVersion},
          {"git", kGitHash},
          {"stage", stage},
          {"command", argv},
          {"inputs", in},
          {"config", config}};
}

std::vector<std::string> recorded_command(const std::vector<std::string>& argv) {
  std::vector<std::string> out;
  auto starts = [](const std::string& a, const char* prefix) { return a.rfind(prefix, 0) == 0; };
  for (std::size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (a == "--resume" || a == "-q" || a == "--quiet" || a == "--merge" || a == "--mpi" || a == "--virtual") continue;
    if (starts(a, "--shard=") || starts(a, "--until=") || starts(a, "--threads=")) continue;
    if (a == "--threads" || a == "-j" || a == "--shard" || a == "--until") {
      ++i;
      continue;
    }
    out.push_back(argv[i]);
  }
  return out;
}

}  // namespace raysweep::pipeline
