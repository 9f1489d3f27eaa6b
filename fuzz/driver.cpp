// The deterministic fuzz driver: main() for a target's LLVMFuzzerTestOneInput when libFuzzer is not used
// (the GCC build, CI, ctest label `fuzz`).
//
//   fuzz_<name> [options] CORPUS...        CORPUS: files or folders (their regular files, sorted by name)
//     --runs N          mutated executions after the corpus replay (default 1000)
//     --seed S          the mutation schedule's seed (default 1); same seed, corpus and N: same inputs
//     --timeout SEC     per-input time bound; longer is a hang, a finding (default 10)
//     --max-seconds SEC stop mutating after this wall time (default 0: no cap); the count run is printed
//     --max-len BYTES   mutated inputs are cut to this size (default 1 MiB)
//     --findings DIR    where inputs that found something are written (default ./fuzz-findings)
//     --replay-only     run the corpus files unmutated and stop (regressions)
//     --verbose         print each input's origin and the aosr error it was refused with (if any)
//
// 1. Replay: every corpus file runs as it is (seeds and committed regressions).
// 2. Mutation: execution k (0 <= k < N) takes corpus file k mod size, and applies 1..4 mutations (one half of
//    the time, so most inputs stay near-valid) drawn from a generator seeded by (S, k): byte flips, interesting
//    bytes, inserts, deletes, duplicated ranges, splices with another corpus file, truncation, and
//    structure-aware mutations chosen by the input's form:
//      JSON  (starts with '{' or '[' and parses): a random node becomes an extreme number (0, -1, 1e308,
//            2^63-1, 2^64-1, 5e-324, ...), a scaled copy of itself, a "NaN"/"inf"/empty/long/path string,
//            a string of the corpus dictionary (every key and string value seen in the corpus), another type
//            (null, bool, [], {}, wrapped); keys are dropped, duplicated or added; arrays are emptied, cut
//            or grown; a subtree is replaced by one of the same key from another corpus file.
//      FITS  (starts with "SIMPLE  ="): a header card (BITPIX, NAXIS, NAXISn, BSCALE, BZERO, BLANK, PCOUNT,
//            GCOUNT, ...) gets an extreme value, is removed, duplicated or added (NAXIS3, BLANK, ZIMAGE,
//            XTENSION); the data is truncated, padded or overwritten with NaN/Inf patterns; an IMAGE
//            extension is appended.
//      PNG   the IHDR width/height/depth/colour type get extreme values, chunks are dropped, duplicated or
//            cut; CRCs are recomputed (mostly) so the decoder gets past them.
//      TIFF  first-IFD entries get extreme values, types and counts, or offsets past the end.
//    The generator is splitmix64 with modulo draws (no std distributions), so the schedule is the same for
//    every compiler and standard library.
// 3. Verdict. The target swallows aosr errors (fuzz_common.hpp). An exception that escapes it (any type,
//    including aosr::Error the target did not expect) is a finding: printed with its demangled type and
//    message, the input saved to DIR and shown in hex; distinct findings (type + message head) are counted.
//    A crash or abort (SIGSEGV, SIGABRT from `terminate called`, ...) saves the input from the signal handler
//    (ASan's own report comes first under -fsanitize=address), and an input running longer than --timeout is
//    reported by a watchdog thread, which saves it and exits with status 3.
//    The exit status is 0 only when nothing was found.
#include <cxxabi.h>
#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cctype>
#include <cinttypes>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>
#include <typeinfo>
#include <vector>

#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);
extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) __attribute__((weak));
// Present when linked with a sanitizer runtime: called before the process dies of a sanitizer report.
extern "C" void __sanitizer_set_death_callback(void (*callback)(void)) __attribute__((weak));

namespace {

using Bytes = std::vector<uint8_t>;
namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------------------
// Deterministic randomness.

struct Rng {
  uint64_t state;
  explicit Rng(uint64_t seed) : state(seed) {}
  uint64_t Next() {
    uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  size_t Below(size_t n) { return n == 0 ? 0 : size_t(Next() % n); }
  bool OneIn(size_t n) { return Below(n) == 0; }
};

// ---------------------------------------------------------------------------------------------------------
// State the signal handlers and the watchdog read.

const uint8_t* g_input = nullptr;
std::atomic<size_t> g_input_size{0};
std::atomic<int64_t> g_started_ns{0};  // 0: not running an input
char g_crash_path[4096] = {};
char g_origin[512] = {};  // "seed <file>" or "mutation k of <file>"
std::string g_target;

int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// Async-signal-safe output.
void SafeWrite(int fd, const char* s, size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd, s, n);
    if (w <= 0) return;
    s += w;
    n -= size_t(w);
  }
}
void SafeWrite(int fd, const char* s) { SafeWrite(fd, s, std::strlen(s)); }

void SafeHex(const uint8_t* data, size_t size, size_t limit) {
  static const char digits[] = "0123456789abcdef";
  char line[3 * 32 + 2];
  for (size_t i = 0; i < size && i < limit; i += 32) {
    size_t k = 0;
    for (size_t j = i; j < size && j < i + 32 && j < limit; ++j) {
      line[k++] = digits[data[j] >> 4];
      line[k++] = digits[data[j] & 15];
      line[k++] = ' ';
    }
    line[k++] = '\n';
    SafeWrite(2, line, k);
  }
  if (size > limit) SafeWrite(2, "...\n");
}

// Saves the current input to g_crash_path and prints where it came from (async-signal-safe).
void DumpCurrentInput(const char* what) {
  const size_t size = g_input_size.load();
  SafeWrite(2, "\n==aosr-fuzz== ");
  SafeWrite(2, what);
  SafeWrite(2, " in ");
  SafeWrite(2, g_target.c_str());
  SafeWrite(2, " on ");
  SafeWrite(2, g_origin);
  SafeWrite(2, "\n==aosr-fuzz== input saved to ");
  SafeWrite(2, g_crash_path);
  SafeWrite(2, "\n");
  if (g_input != nullptr) {
    const int fd = ::open(g_crash_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      SafeWrite(fd, reinterpret_cast<const char*>(g_input), size);
      ::close(fd);
    }
    SafeHex(g_input, size, 512);
  }
}

void OnSignal(int sig) {
  DumpCurrentInput(sig == SIGABRT ? "FINDING: abort (e.g. terminate called)"
                   : sig == SIGSEGV ? "FINDING: SIGSEGV"
                   : sig == SIGBUS  ? "FINDING: SIGBUS"
                   : sig == SIGFPE  ? "FINDING: SIGFPE"
                                    : "FINDING: fatal signal");
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

void OnSanitizerDeath() { DumpCurrentInput("FINDING: sanitizer report"); }

void Watchdog(double timeout_s) {
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    const int64_t started = g_started_ns.load();
    if (started != 0 && double(NowNs() - started) * 1e-9 > timeout_s) {
      DumpCurrentInput("FINDING: hang (input ran longer than --timeout)");
      std::fflush(nullptr);
      std::error_code ec;  // _exit skips the atexit removal of the scratch folder
      std::filesystem::remove_all(aosr::fuzz::ScratchDir(), ec);
      ::_exit(3);
    }
  }
}

// ---------------------------------------------------------------------------------------------------------
// Interesting values.

const char* const kInterestingNumbers[] = {
    "0", "-0", "1", "-1", "2", "3", "4", "7", "8", "15", "16", "17", "255", "256", "1023", "1024", "4096",
    "4097", "8192", "65535", "65536", "100000", "1000000", "2147483647", "2147483648", "-2147483648",
    "4294967295", "4294967296", "9007199254740993", "9223372036854775807", "-9223372036854775808",
    "18446744073709551615", "99999999999999999999999", "0.5", "-0.5", "1.5", "1e-9", "1e-300", "5e-324",
    "1e9", "1e12", "1e18", "1e300", "1e308", "1.7976931348623157e308", "-1e308", "2.5e-1", "3.0000000001"};

const char* const kInterestingStrings[] = {"", "NaN", "nan", "inf", "-inf", "Infinity", "1e999", "0", "-1",
                                           "x", "/nonexistent/file.fits", "/dev/zero", "/dev/null", ".",
                                           "..", "/", "../../..", "manifest.json", "a.json", "\u00e9\u4e2d",
                                           "\t\n", "comment", "none", "true"};

nlohmann::json InterestingNumber(Rng& rng) {
  const std::string text = kInterestingNumbers[rng.Below(std::size(kInterestingNumbers))];
  return nlohmann::json::parse(text);  // integers stay integers (unsigned above 2^63), the rest doubles
}

// ---------------------------------------------------------------------------------------------------------
// JSON mutations.

void CollectNodes(nlohmann::json& j, std::vector<nlohmann::json*>* out) {
  out->push_back(&j);
  if (j.is_object())
    for (auto& [k, v] : j.items()) CollectNodes(v, out);
  else if (j.is_array())
    for (auto& v : j) CollectNodes(v, out);
}

struct Corpus {
  std::vector<Bytes> files;
  std::vector<std::string> names;
  std::vector<std::string> dictionary;                      // keys and string values of the JSON files
  std::map<std::string, std::vector<nlohmann::json>> by_key;  // values seen under each key
};

bool LooksJson(const Bytes& b) {
  for (uint8_t c : b) {
    if (c == ' ' || c == '\n' || c == '\r' || c == '\t') continue;
    return c == '{' || c == '[';
  }
  return false;
}

void MutateJsonNode(nlohmann::json* root, Rng& rng, const Corpus& corpus) {
  std::vector<nlohmann::json*> nodes;
  CollectNodes(*root, &nodes);
  nlohmann::json& n = *nodes[rng.Below(nodes.size())];
  switch (rng.Below(12)) {
    case 0:
    case 1:
      n = InterestingNumber(rng);
      break;
    case 2:  // a scaled or shifted copy of a number (valid-looking extremes)
      if (n.is_number()) {
        const double v = n.get<double>();
        const double factors[] = {-1, 0.5, 2, 10, 1000, 1e6, 1e-6, 0};
        const double f = factors[rng.Below(std::size(factors))];
        if (n.is_number_integer() && rng.OneIn(2) && std::abs(v) < 9e18)  // ±1, without signed overflow
          n = n.get<long long>() + (rng.OneIn(2) ? 1 : -1);
        else if (n.is_number_integer() && std::abs(v * f) < 9e18 && std::floor(v * f) == v * f) n = (long long)(v * f);
        else n = v * f;
      } else {
        n = InterestingNumber(rng);
      }
      break;
    case 3:
      if (rng.OneIn(3)) n = std::string(size_t(1) << (4 + rng.Below(12)), 'a');
      else n = kInterestingStrings[rng.Below(std::size(kInterestingStrings))];
      break;
    case 4:
    case 5:
      if (!corpus.dictionary.empty()) n = corpus.dictionary[rng.Below(corpus.dictionary.size())];
      break;
    case 6: {  // another type
      const int t = int(rng.Below(7));
      if (t == 0) n = nullptr;
      else if (t == 1) n = bool(rng.OneIn(2));
      else if (t == 2) n = nlohmann::json::array();
      else if (t == 3) n = nlohmann::json::object();
      else if (t == 4) n = nlohmann::json::array({n});
      else if (t == 5) n = nlohmann::json{{"x", n}};
      else n = n.dump();
      break;
    }
    case 7:  // drop a key or element
      if (n.is_object() && !n.empty()) {
        auto it = n.begin();
        std::advance(it, long(rng.Below(n.size())));
        n.erase(it);
      } else if (n.is_array() && !n.empty()) {
        n.erase(n.begin() + long(rng.Below(n.size())));
      }
      break;
    case 8:  // grow an array / add a key
      if (n.is_array() && !n.empty()) {
        const nlohmann::json e = n[rng.Below(n.size())];
        const size_t copies = rng.OneIn(4) ? 1 + rng.Below(200) : 1 + rng.Below(3);
        for (size_t i = 0; i < copies; ++i) n.push_back(e);
      } else if (n.is_object()) {
        const std::string key = corpus.dictionary.empty() || rng.OneIn(3)
                                    ? std::string(rng.OneIn(2) ? "unknown_field" : "comment_fuzz")
                                    : corpus.dictionary[rng.Below(corpus.dictionary.size())];
        n[key] = InterestingNumber(rng);
      } else {
        n = nlohmann::json::array({n, n});
      }
      break;
    case 9:  // empty or cut an array
      if (n.is_array()) {
        if (rng.OneIn(2)) n = nlohmann::json::array();
        else if (n.size() > 1) n.erase(n.begin() + long(1 + rng.Below(n.size() - 1)), n.end());
      } else if (n.is_object()) {
        n = nlohmann::json::object();
      }
      break;
    case 10:  // a value seen under the same key elsewhere (cross-over)
    case 11:
      if (n.is_object() && !n.empty()) {
        auto it = n.begin();
        std::advance(it, long(rng.Below(n.size())));
        auto found = corpus.by_key.find(it.key());
        if (found != corpus.by_key.end() && !found->second.empty())
          it.value() = found->second[rng.Below(found->second.size())];
      } else if (n.is_array() && !n.empty()) {
        std::swap(n[rng.Below(n.size())], n[rng.Below(n.size())]);
      }
      break;
  }
}

// ---------------------------------------------------------------------------------------------------------
// FITS mutations.

const char* const kFitsKeys[] = {"BITPIX", "NAXIS", "NAXIS1", "NAXIS2", "NAXIS3", "BSCALE",
                                 "BZERO",  "BLANK", "PCOUNT", "GCOUNT", "EXTEND", "SIMPLE"};
const char* const kFitsValues[] = {"0",  "-1", "1",  "2",   "3",  "4",  "5",  "7",
                                   "8",  "16", "32", "64",  "-8", "-16", "-32", "-64",
                                   "999", "1000000", "2147483647", "-2147483648", "9223372036854775807",
                                   "99999999999999999999", "1E308", "-1E308", "1E-308", "0.0", "NAN",
                                   "'abc'", "T", "F", "65536", "46341", "3037000500"};

std::string FitsCard(const std::string& key, const std::string& value) {
  std::string card = key;
  card.resize(8, ' ');
  card += "= ";
  std::string v = value;
  if (v.size() < 20) v = std::string(20 - v.size(), ' ') + v;
  card += v;
  card.resize(80, ' ');
  return card;
}

// Header cards of the first HDU: [0, end_card] (end_card is the END card's index, or -1).
int FitsEndCard(const Bytes& b) {
  for (size_t i = 0; i + 80 <= b.size(); i += 80)
    if (std::memcmp(&b[i], "END", 3) == 0 && b[i + 3] == ' ')
      return int(i / 80);
  return -1;
}

void MutateFits(Bytes* b, Rng& rng) {
  const int end = FitsEndCard(*b);
  if (end < 0) return;
  const size_t header_bytes = (size_t(end) * 80 / 2880 + 1) * 2880;
  switch (rng.Below(9)) {
    case 0:
    case 1:
    case 2: {  // an extreme value for a structural card (or any card)
      std::vector<int> cards;
      for (int c = 0; c < end; ++c) {
        const std::string key(reinterpret_cast<const char*>(&(*b)[size_t(c) * 80]), 8);
        for (const char* k : kFitsKeys)
          if (key.rfind(k, 0) == 0 && (key.size() == std::strlen(k) || key[std::strlen(k)] == ' ')) cards.push_back(c);
      }
      const int c = cards.empty() || rng.OneIn(5) ? int(rng.Below(size_t(end))) : cards[rng.Below(cards.size())];
      const std::string key(reinterpret_cast<const char*>(&(*b)[size_t(c) * 80]), 8);
      const std::string card = FitsCard(key, kFitsValues[rng.Below(std::size(kFitsValues))]);
      std::memcpy(&(*b)[size_t(c) * 80], card.data(), 80);
      break;
    }
    case 3: {  // remove a card (the rest moves up; a blank card before END keeps the block)
      if (end < 2) break;
      const size_t c = 1 + rng.Below(size_t(end - 1));
      b->erase(b->begin() + long(c * 80), b->begin() + long(c * 80 + 80));
      const std::string blank(80, ' ');
      b->insert(b->begin() + long((end - 1) * 80), blank.begin(), blank.end());  // END moved up to end - 1
      break;
    }
    case 4: {  // add a card before END
      const char* const extra[] = {"NAXIS3  =                    5", "BLANK   =                    0",
                                   "BSCALE  =                    0", "BZERO   =               1E+300",
                                   "ZIMAGE  =                    T", "NAXIS4  =                    2",
                                   "XTENSION= 'IMAGE   '",           "NAXIS   =                    1",
                                   "GCOUNT  =                    2", "PCOUNT  =               100000",
                                   "CONTINUE  'abc'",                "HIERARCH A B C = 1"};
      std::string card = extra[rng.Below(std::size(extra))];
      card.resize(80, ' ');
      // Overwrite END and write END after it (stays within the header most of the time).
      if (size_t(end + 1) * 80 + 80 <= b->size()) {
        std::memcpy(&(*b)[size_t(end) * 80], card.data(), 80);
        std::string e = "END";
        e.resize(80, ' ');
        std::memcpy(&(*b)[size_t(end + 1) * 80], e.data(), 80);
      }
      break;
    }
    case 5: {  // truncate the data, or the header
      const size_t cut = rng.OneIn(4) ? rng.Below(header_bytes) : header_bytes + rng.Below(b->size() - header_bytes + 1);
      b->resize(std::min(cut, b->size()));
      break;
    }
    case 6: {  // pad or overwrite data with NaN / Inf / huge patterns
      if (b->size() > header_bytes) {
        const uint8_t patterns[][8] = {{0x7f, 0xc0, 0, 0, 0, 0, 0, 0},          {0x7f, 0x80, 0, 0, 0, 0, 0, 0},
                                       {0xff, 0xf0, 0, 0, 0, 0, 0, 0},          {0x7f, 0xef, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff},
                                       {0x80, 0, 0, 0, 0, 0, 0, 0},             {0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff}};
        const auto& p = patterns[rng.Below(std::size(patterns))];
        const size_t at = header_bytes + rng.Below(b->size() - header_bytes);
        const size_t count = 1 + rng.Below(64);
        for (size_t i = 0; i < count * 8 && at + i < b->size(); ++i) (*b)[at + i] = p[i % 8];
      } else {
        b->resize(b->size() + 2880, 0);
      }
      break;
    }
    case 7: {  // append a copy of the HDU as an IMAGE extension
      Bytes ext = *b;
      if (ext.size() >= 80) {
        const std::string card = FitsCard("XTENSION", "'IMAGE   '");
        std::memcpy(ext.data(), card.data(), 80);
      }
      if (b->size() % 2880 != 0) b->resize((b->size() / 2880 + 1) * 2880, 0);
      b->insert(b->end(), ext.begin(), ext.end());
      break;
    }
    case 8: {  // an empty primary HDU in front (NAXIS = 0) so the reader looks for an extension
      std::string h = FitsCard("SIMPLE", "T") + FitsCard("BITPIX", "8") + FitsCard("NAXIS", "0") + FitsCard("EXTEND", "T");
      std::string e = "END";
      e.resize(80, ' ');
      h += e;
      h.resize(2880, ' ');
      if (b->size() >= 80) {
        const std::string card = FitsCard("XTENSION", "'IMAGE   '");
        std::memcpy(b->data(), card.data(), 80);
      }
      b->insert(b->begin(), h.begin(), h.end());
      break;
    }
  }
}

// ---------------------------------------------------------------------------------------------------------
// PNG and TIFF mutations.

uint32_t Crc32(const uint8_t* p, size_t n) {
  uint32_t c = 0xffffffffu;
  for (size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return ~c;
}
uint32_t Be32(const uint8_t* p) { return uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 | p[3]; }
void PutBe32(uint8_t* p, uint32_t v) {
  p[0] = uint8_t(v >> 24);
  p[1] = uint8_t(v >> 16);
  p[2] = uint8_t(v >> 8);
  p[3] = uint8_t(v);
}

bool IsPng(const Bytes& b) { return b.size() >= 8 && std::memcmp(b.data(), "\x89PNG\r\n\x1a\n", 8) == 0; }

struct PngChunk {
  size_t offset;  // of the length field
  uint32_t length;
};
std::vector<PngChunk> PngChunks(const Bytes& b) {
  std::vector<PngChunk> out;
  size_t at = 8;
  while (at + 12 <= b.size()) {
    const uint32_t len = Be32(&b[at]);
    if (at + 12 + size_t(len) > b.size()) break;
    out.push_back({at, len});
    at += 12 + size_t(len);
  }
  return out;
}

void FixPngCrcs(Bytes* b) {
  for (const PngChunk& c : PngChunks(*b)) PutBe32(&(*b)[c.offset + 8 + c.length], Crc32(&(*b)[c.offset + 4], 4 + c.length));
}

void MutatePng(Bytes* b, Rng& rng) {
  std::vector<PngChunk> chunks = PngChunks(*b);
  if (chunks.empty()) return;
  const uint32_t dims[] = {0, 1, 2, 3, 255, 256, 65535, 65536, 1u << 20, 1000000, 0x7fffffffu, 0x80000000u, 0xffffffffu};
  switch (rng.Below(5)) {
    case 0:
    case 1:  // IHDR fields
      if (std::memcmp(&(*b)[chunks[0].offset + 4], "IHDR", 4) == 0 && chunks[0].length >= 13) {
        uint8_t* d = &(*b)[chunks[0].offset + 8];
        switch (rng.Below(4)) {
          case 0: PutBe32(d, dims[rng.Below(std::size(dims))]); break;
          case 1: PutBe32(d + 4, dims[rng.Below(std::size(dims))]); break;
          case 2: d[8] = uint8_t(std::vector<int>{0, 1, 2, 3, 4, 8, 16, 32, 255}[rng.Below(9)]); break;
          default: d[9 + rng.Below(4)] = uint8_t(rng.Below(8)); break;
        }
      }
      break;
    case 2: {  // drop a chunk
      const PngChunk c = chunks[rng.Below(chunks.size())];
      b->erase(b->begin() + long(c.offset), b->begin() + long(c.offset + 12 + c.length));
      break;
    }
    case 3: {  // duplicate a chunk
      const PngChunk c = chunks[rng.Below(chunks.size())];
      const Bytes copy(b->begin() + long(c.offset), b->begin() + long(c.offset + 12 + c.length));
      b->insert(b->begin() + long(c.offset), copy.begin(), copy.end());
      break;
    }
    default: {  // corrupt compressed data inside a chunk
      const PngChunk c = chunks[rng.Below(chunks.size())];
      if (c.length > 0) (*b)[c.offset + 8 + rng.Below(c.length)] ^= uint8_t(1 + rng.Below(255));
      break;
    }
  }
  if (!rng.OneIn(10)) FixPngCrcs(b);
}

bool IsTiff(const Bytes& b) {
  return b.size() >= 8 && (std::memcmp(b.data(), "II*\0", 4) == 0 || std::memcmp(b.data(), "MM\0*", 4) == 0);
}

void MutateTiff(Bytes* b, Rng& rng) {
  const bool le = (*b)[0] == 'I';
  auto get16 = [&](size_t at) -> uint32_t {
    return le ? uint32_t((*b)[at]) | uint32_t((*b)[at + 1]) << 8 : uint32_t((*b)[at]) << 8 | (*b)[at + 1];
  };
  auto get32 = [&](size_t at) -> uint32_t {
    return le ? get16(at) | get16(at + 2) << 16 : get16(at) << 16 | get16(at + 2);
  };
  auto put16 = [&](size_t at, uint32_t v) {
    (*b)[at + (le ? 0 : 1)] = uint8_t(v);
    (*b)[at + (le ? 1 : 0)] = uint8_t(v >> 8);
  };
  auto put32 = [&](size_t at, uint32_t v) {
    put16(at + (le ? 0 : 2), v & 0xffff);
    put16(at + (le ? 2 : 0), v >> 16);
  };
  const size_t ifd = get32(4);
  if (ifd + 2 > b->size()) return;
  const size_t count = get16(ifd);
  if (count == 0 || ifd + 2 + count * 12 > b->size()) return;
  const size_t e = ifd + 2 + rng.Below(count) * 12;
  const uint32_t values[] = {0, 1, 2, 3, 4, 8, 16, 32, 64, 255, 65535, 65536, 1u << 24, 0x7fffffffu, 0xffffffffu};
  switch (rng.Below(4)) {
    case 0:  // value (SHORT or LONG in place)
      if (get16(e + 2) == 3) put16(e + 8, values[rng.Below(std::size(values))] & 0xffff);
      else put32(e + 8, values[rng.Below(std::size(values))]);
      break;
    case 1: put16(e + 2, uint32_t(rng.Below(20))); break;            // type
    case 2: put32(e + 4, values[rng.Below(std::size(values))]); break;  // count
    default: put32(e + 8, uint32_t(b->size() + rng.Below(1u << 20))); break;  // offset past the end
  }
}

// ---------------------------------------------------------------------------------------------------------
// Generic byte mutations.

void MutateBytes(Bytes* b, Rng& rng, const Corpus& corpus) {
  const uint8_t interesting[] = {0, 0xff, 0x7f, 0x80, '0', '9', '-', '.', 'e', '"', '{', '}', '[', ']', ',', ':', '\\', ' '};
  switch (rng.Below(9)) {
    case 0:
      if (!b->empty()) (*b)[rng.Below(b->size())] ^= uint8_t(1u << rng.Below(8));
      break;
    case 1:
      if (!b->empty()) (*b)[rng.Below(b->size())] = interesting[rng.Below(std::size(interesting))];
      break;
    case 2: {
      const size_t n = 1 + rng.Below(8);
      const size_t at = rng.Below(b->size() + 1);
      Bytes ins(n);
      for (auto& c : ins) c = uint8_t(rng.Next());
      b->insert(b->begin() + long(at), ins.begin(), ins.end());
      break;
    }
    case 3:
      if (!b->empty()) {
        const size_t at = rng.Below(b->size());
        const size_t n = 1 + rng.Below(std::min<size_t>(64, b->size() - at));
        b->erase(b->begin() + long(at), b->begin() + long(at + n));
      }
      break;
    case 4:
      if (!b->empty()) {
        const size_t from = rng.Below(b->size());
        const size_t n = 1 + rng.Below(std::min<size_t>(256, b->size() - from));
        const Bytes chunk(b->begin() + long(from), b->begin() + long(from + n));
        b->insert(b->begin() + long(rng.Below(b->size() + 1)), chunk.begin(), chunk.end());
      }
      break;
    case 5: {  // splice with another corpus file
      const Bytes& other = corpus.files[rng.Below(corpus.files.size())];
      const size_t keep = rng.Below(b->size() + 1);
      const size_t from = rng.Below(other.size() + 1);
      b->resize(keep);
      b->insert(b->end(), other.begin() + long(from), other.end());
      break;
    }
    case 6: {  // a token: dictionary string (quoted or not) or number text
      std::string t = rng.OneIn(2) || corpus.dictionary.empty()
                          ? std::string(kInterestingNumbers[rng.Below(std::size(kInterestingNumbers))])
                          : "\"" + corpus.dictionary[rng.Below(corpus.dictionary.size())] + "\"";
      b->insert(b->begin() + long(rng.Below(b->size() + 1)), t.begin(), t.end());
      break;
    }
    case 7:
      b->resize(rng.Below(b->size() + 1));
      break;
    case 8: {  // replace a run of digits by an interesting number
      std::vector<size_t> starts;
      for (size_t i = 0; i < b->size(); ++i)
        if (std::isdigit((*b)[i]) && (i == 0 || !std::isdigit((*b)[i - 1]))) starts.push_back(i);
      if (starts.empty()) break;
      const size_t s = starts[rng.Below(starts.size())];
      size_t e = s;
      while (e < b->size() && (std::isdigit((*b)[e]) || (*b)[e] == '.')) ++e;
      const std::string t = kInterestingNumbers[rng.Below(std::size(kInterestingNumbers))];
      b->erase(b->begin() + long(s), b->begin() + long(e));
      b->insert(b->begin() + long(s), t.begin(), t.end());
      break;
    }
  }
}

Bytes Mutate(const Bytes& seed, Rng& rng, const Corpus& corpus, size_t max_len) {
  Bytes b = seed;
  const size_t count = rng.OneIn(2) ? 1 : 2 + rng.Below(3);  // half single mutations: most stay near-valid
  for (size_t m = 0; m < count; ++m) {
    const bool structured = !rng.OneIn(4);  // 3 in 4 mutations use the input's structure when it has one
    if (structured && LooksJson(b)) {
      nlohmann::json j = nlohmann::json::parse(b.begin(), b.end(), nullptr, false);
      if (!j.is_discarded()) {
        MutateJsonNode(&j, rng, corpus);
        const std::string text = rng.OneIn(2) ? j.dump(2) : j.dump();
        b.assign(text.begin(), text.end());
        continue;
      }
    }
    if (structured && b.size() >= 9 && std::memcmp(b.data(), "SIMPLE  =", 9) == 0) {
      MutateFits(&b, rng);
      continue;
    }
    if (structured && IsPng(b)) {
      MutatePng(&b, rng);
      continue;
    }
    if (structured && IsTiff(b)) {
      MutateTiff(&b, rng);
      continue;
    }
    MutateBytes(&b, rng, corpus);
  }
  if (b.size() > max_len) b.resize(max_len);
  return b;
}

// ---------------------------------------------------------------------------------------------------------
// Corpus loading.

void AddDictionary(const nlohmann::json& j, Corpus* c, std::set<std::string>* seen) {
  if (j.is_object()) {
    for (auto& [k, v] : j.items()) {
      if (seen->insert(k).second) c->dictionary.push_back(k);
      auto& list = c->by_key[k];
      if (list.size() < 16) list.push_back(v);
      AddDictionary(v, c, seen);
    }
  } else if (j.is_array()) {
    for (const auto& v : j) AddDictionary(v, c, seen);
  } else if (j.is_string()) {
    const std::string s = j.get<std::string>();
    if (s.size() <= 64 && seen->insert(s).second) c->dictionary.push_back(s);
  }
}

bool LoadCorpus(const std::vector<std::string>& paths, Corpus* c) {
  std::vector<std::string> files;
  for (const std::string& p : paths) {
    if (fs::is_directory(p)) {
      std::vector<std::string> in_dir;
      for (const auto& e : fs::directory_iterator(p))
        if (e.is_regular_file() && e.path().filename() != "README.md") in_dir.push_back(e.path().string());
      std::sort(in_dir.begin(), in_dir.end());
      files.insert(files.end(), in_dir.begin(), in_dir.end());
    } else if (fs::is_regular_file(p)) {
      files.push_back(p);
    } else {
      std::fprintf(stderr, "%s: no such corpus file or folder: %s\n", g_target.c_str(), p.c_str());
      return false;
    }
  }
  std::set<std::string> seen;
  for (const std::string& f : files) {
    std::ifstream in(f, std::ios::binary);
    Bytes b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (LooksJson(b)) {
      const nlohmann::json j = nlohmann::json::parse(b.begin(), b.end(), nullptr, false);
      if (!j.is_discarded()) AddDictionary(j, c, &seen);
    }
    c->files.push_back(std::move(b));
    c->names.push_back(f);
  }
  return true;
}

// ---------------------------------------------------------------------------------------------------------
// Running inputs.

struct Stats {
  uint64_t executions = 0;
  uint64_t findings = 0;
  std::set<std::string> distinct;
};

std::string Demangle(const char* name) {
  int status = 0;
  char* d = abi::__cxa_demangle(name, nullptr, nullptr, &status);
  std::string out = status == 0 && d ? d : name;
  std::free(d);
  return out;
}

void Report(const std::string& type, const std::string& what, const Bytes& input, const std::string& findings_dir,
            Stats* stats) {
  ++stats->findings;
  const std::string key = type + ": " + what.substr(0, 120);
  const bool first = stats->distinct.insert(key).second;
  std::error_code ec;
  fs::create_directories(findings_dir, ec);
  const std::string path = findings_dir + "/" + g_target + "-finding-" + std::to_string(stats->findings) + ".bin";
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(input.data()), std::streamsize(input.size()));
  std::fprintf(stderr, "\n==aosr-fuzz== FINDING%s: %s escaped %s on %s\n==aosr-fuzz== what(): %s\n==aosr-fuzz== input saved to %s (%zu bytes)\n",
               first ? "" : " (again)", type.c_str(), g_target.c_str(), g_origin, what.c_str(), path.c_str(),
               input.size());
  if (first) {
    std::fflush(stderr);
    SafeHex(input.data(), input.size(), 256);
  }
}

bool g_verbose = false;

void RunOne(const Bytes& input, const std::string& findings_dir, Stats* stats) {
  aosr::fuzz::last_refusal.clear();
  // libFuzzer passes a buffer of exactly `size` bytes; so do we (ASan then sees reads past the end).
  Bytes copy = input;
  g_input = copy.data();
  g_input_size = copy.size();
  g_started_ns = NowNs();
  try {
    LLVMFuzzerTestOneInput(copy.data(), copy.size());
  } catch (const std::exception& e) {
    g_started_ns = 0;
    Report(Demangle(typeid(e).name()), e.what(), input, findings_dir, stats);
  } catch (...) {
    g_started_ns = 0;
    Report("(non-std exception)", "", input, findings_dir, stats);
  }
  g_started_ns = 0;
  g_input = nullptr;
  ++stats->executions;
  if (g_verbose)
    std::printf("%s: %s\n", g_origin, aosr::fuzz::last_refusal.empty() ? "ok" : aosr::fuzz::last_refusal.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  g_target = fs::path(argv[0]).filename().string();
  uint64_t runs = 1000, seed = 1;
  double timeout_s = 10, max_seconds = 0;
  size_t max_len = 1 << 20;
  std::string findings_dir = "fuzz-findings";
  bool replay_only = false;
  std::vector<std::string> paths;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s: %s needs a value\n", g_target.c_str(), a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--runs") runs = std::stoull(value());
    else if (a == "--seed") seed = std::stoull(value());
    else if (a == "--timeout") timeout_s = std::stod(value());
    else if (a == "--max-seconds") max_seconds = std::stod(value());
    else if (a == "--max-len") max_len = std::stoull(value());
    else if (a == "--findings") findings_dir = value();
    else if (a == "--replay-only") replay_only = true;
    else if (a == "--verbose") g_verbose = true;
    else if (a == "--help" || a == "-h") {
      std::printf("usage: %s [--runs N] [--seed S] [--timeout SEC] [--max-seconds SEC] [--max-len BYTES]\n"
                  "          [--findings DIR] [--replay-only] CORPUS...\n(see fuzz/driver.cpp and fuzz/README.md)\n",
                  g_target.c_str());
      return 0;
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "%s: unknown option %s\n", g_target.c_str(), a.c_str());
      return 2;
    } else {
      paths.push_back(a);
    }
  }
  Corpus corpus;
  if (!LoadCorpus(paths, &corpus)) return 2;
  if (corpus.files.empty()) {
    std::fprintf(stderr, "%s: empty corpus\n", g_target.c_str());
    return 2;
  }
  if (LLVMFuzzerInitialize) LLVMFuzzerInitialize(&argc, &argv);

  {
    std::error_code ec;
    fs::create_directories(findings_dir, ec);
    const std::string crash = fs::absolute(findings_dir).string() + "/" + g_target + "-crash-" + std::to_string(::getpid()) + ".bin";
    std::snprintf(g_crash_path, sizeof g_crash_path, "%s", crash.c_str());
  }
  if (__sanitizer_set_death_callback) {
    __sanitizer_set_death_callback(OnSanitizerDeath);
    ::signal(SIGABRT, OnSignal);  // the sanitizers leave SIGABRT alone by default
  } else {
    for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) ::signal(sig, OnSignal);
  }
  std::thread(Watchdog, timeout_s).detach();

  Stats stats;
  const auto t0 = std::chrono::steady_clock::now();
  for (size_t i = 0; i < corpus.files.size(); ++i) {
    std::snprintf(g_origin, sizeof g_origin, "corpus file %s (unmutated)", corpus.names[i].c_str());
    RunOne(corpus.files[i], findings_dir, &stats);
  }
  const uint64_t replayed = stats.executions;
  uint64_t mutated = 0;
  bool capped = false;
  if (!replay_only) {
    for (uint64_t k = 0; k < runs; ++k) {
      if (max_seconds > 0 && std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > max_seconds) {
        capped = true;
        break;
      }
      Rng rng(seed * 0x100000001B3ull ^ (k + 1) * 0x9E3779B97F4A7C15ull);
      const size_t which = size_t(k % corpus.files.size());
      std::snprintf(g_origin, sizeof g_origin, "mutation %" PRIu64 " (--seed %" PRIu64 ") of %s", k, seed,
                    corpus.names[which].c_str());
      const Bytes input = Mutate(corpus.files[which], rng, corpus, max_len);
      RunOne(input, findings_dir, &stats);
      ++mutated;
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("%s: %zu corpus files, %" PRIu64 " executions (%" PRIu64 " replayed, %" PRIu64
              " mutated, seed %" PRIu64 "%s) in %.1f s, %" PRIu64 " findings (%zu distinct)\n",
              g_target.c_str(), corpus.files.size(), stats.executions, replayed, mutated, seed,
              capped ? ", stopped by --max-seconds" : "", seconds, stats.findings, stats.distinct.size());
  std::printf("  entry-point calls: %" PRIu64 " returned, %" PRIu64 " refused with an aosr error\n",
              aosr::fuzz::accepted_count, aosr::fuzz::refused_count);
  for (const std::string& d : stats.distinct) std::printf("  finding: %s\n", d.c_str());
  return stats.findings == 0 ? 0 : 1;
}
