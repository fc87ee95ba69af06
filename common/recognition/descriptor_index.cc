#include "common/recognition/descriptor_index.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <queue>
#include <sstream>
#include <stdexcept>

#include <hnswlib/hnswlib.h>
#include <xxhash.h>

#include "common/features/features.h"
#include "common/recognition/descriptor_matching.h"
#include "common/recognition/kd_tree.h"
#include "common/util/logging.h"
#include "common/util/timer.h"

namespace placerec {
namespace {

// Squared Euclidean distance of 128-byte descriptors for hnswlib.
class DescriptorSpace : public hnswlib::SpaceInterface<int> {
 public:
  size_t get_data_size() override { return kDescriptorSize; }
  hnswlib::DISTFUNC<int> get_dist_func() override { return &Distance; }
  void* get_dist_func_param() override { return nullptr; }

 private:
  static int Distance(const void* a, const void* b, const void*) {
    return SquaredDistance(static_cast<const uint8_t*>(a), static_cast<const uint8_t*>(b));
  }
};

// The graph's random layer assignment starts from this seed: the same insertions give the same
// graph in every process.
constexpr size_t kHnswSeed = 100;

// XXH64 (libxxhash) of a byte stream: fast enough to cover every stored descriptor when a map
// opens, and good at telling apart damaged or different contents (no protection against a
// deliberate forgery).
class Hash64 {
 public:
  Hash64() : state_(XXH64_createState()) {
    CHECK(state_ != nullptr);
    XXH64_reset(state_, 0);
  }
  ~Hash64() { XXH64_freeState(state_); }
  Hash64(const Hash64&) = delete;
  Hash64& operator=(const Hash64&) = delete;

  void Update(const void* data, size_t size) { XXH64_update(state_, data, size); }
  uint64_t Digest() const { return XXH64_digest(state_); }

 private:
  XXH64_state_t* state_;
};

// The snapshot file: a fixed header, then the tree's nodes (GrownKdTree::Save) as raw
// native-endian values. A snapshot is a cache of one machine's map, not an exchange format.
constexpr char kSnapshotMagic[16] = "placerec-dindex";
// Version 2: the header below; the nodes of GrownKdTree::Save. (Version 1 held FLANN 1.9's
// KDTreeIndex serialization; such a snapshot is ignored and the tree grown again.)
constexpr uint32_t kSnapshotVersion = 2;
constexpr uint32_t kSnapshotFlann = 1;  // the method field: kFlann's k-d tree

// The payload's values are written as this machine holds them: one of another byte order reads
// them otherwise, so the byte order must match.
std::string PayloadLayout() {
  const uint32_t one = 1;
  uint8_t first_byte;
  std::memcpy(&first_byte, &one, 1);
  return std::string("kd-tree i32 f32 u8 ") + (first_byte == 1 ? "le" : "be");
}

struct SnapshotHeader {
  uint32_t version = kSnapshotVersion;
  uint32_t method = kSnapshotFlann;
  uint32_t descriptor_size = kDescriptorSize;
  uint32_t trees = 1;
  uint64_t adds = 0;            // Add calls covered, from the first
  uint64_t points = 0;          // their descriptors
  uint64_t content_digest = 0;  // DescriptorIndex::ContentDigest(adds)
  uint64_t payload_bytes = 0;
  uint64_t payload_hash = 0;  // Hash64 of the payload

  std::string layout = PayloadLayout();  // at most kLayoutBytes - 1 characters

  static constexpr size_t kLayoutBytes = 32;
  // magic, the fields, the layout, the header hash
  static constexpr size_t kBytes = 16 + 4 * 4 + 5 * 8 + kLayoutBytes + 8;

  std::vector<uint8_t> Encode() const {
    std::vector<uint8_t> bytes(kBytes);
    uint8_t* p = bytes.data();
    auto put = [&p](const void* value, size_t size) {
      std::memcpy(p, value, size);
      p += size;
    };
    put(kSnapshotMagic, 16);
    for (const uint32_t v : {version, method, descriptor_size, trees}) put(&v, 4);
    for (const uint64_t v : {adds, points, content_digest, payload_bytes, payload_hash}) {
      put(&v, 8);
    }
    char layout_field[kLayoutBytes] = {};
    std::memcpy(layout_field, layout.data(), std::min(layout.size(), kLayoutBytes - 1));
    put(layout_field, kLayoutBytes);
    Hash64 hash;
    hash.Update(bytes.data(), kBytes - 8);
    const uint64_t header_hash = hash.Digest();
    put(&header_hash, 8);
    return bytes;
  }

  // The header in `bytes` (kBytes of them), or why they are not one this code can read.
  static StatusOr<SnapshotHeader> Decode(const uint8_t* bytes) {
    if (std::memcmp(bytes, kSnapshotMagic, 16) != 0) {
      return Status::InvalidArgument("not a descriptor index snapshot");
    }
    Hash64 hash;
    hash.Update(bytes, kBytes - 8);
    uint64_t header_hash;
    std::memcpy(&header_hash, bytes + kBytes - 8, 8);
    if (hash.Digest() != header_hash) return Status::InvalidArgument("its header is damaged");
    SnapshotHeader h;
    const uint8_t* p = bytes + 16;
    auto get = [&p](void* value, size_t size) {
      std::memcpy(value, p, size);
      p += size;
    };
    for (uint32_t* v : {&h.version, &h.method, &h.descriptor_size, &h.trees}) get(v, 4);
    for (uint64_t* v : {&h.adds, &h.points, &h.content_digest, &h.payload_bytes, &h.payload_hash}) {
      get(v, 8);
    }
    char layout_field[kLayoutBytes];
    get(layout_field, kLayoutBytes);
    layout_field[kLayoutBytes - 1] = '\0';
    h.layout = layout_field;
    if (h.version != kSnapshotVersion) {
      return Status::InvalidArgument("format version " + std::to_string(h.version) +
                                     ", this build reads version " +
                                     std::to_string(kSnapshotVersion));
    }
    if (h.layout != PayloadLayout()) {
      return Status::InvalidArgument("written with " + h.layout + ", this build has " +
                                     PayloadLayout());
    }
    if (h.method != kSnapshotFlann || h.descriptor_size != kDescriptorSize || h.trees != 1) {
      return Status::InvalidArgument("made for another index (method " + std::to_string(h.method) +
                                     ", " + std::to_string(h.trees) + " trees, " +
                                     std::to_string(h.descriptor_size) + "-byte descriptors)");
    }
    return h;
  }
};

// Closes a FILE* on scope exit.
struct FileCloser {
  void operator()(std::FILE* file) const { std::fclose(file); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

// Archives that write and read raw values through a large buffer, hashing what passes.
class SnapshotWriter {
 public:
  explicit SnapshotWriter(std::FILE* file) : file_(file) { buffer_.reserve(kBufferBytes); }
  template <typename T>
  void save(const T& value) {
    Write(&value, sizeof(value));
  }
  // Writes out what is buffered; false if any write failed.
  bool Flush() {
    hash_.Update(buffer_.data(), buffer_.size());
    if (!buffer_.empty() && std::fwrite(buffer_.data(), buffer_.size(), 1, file_) != 1) {
      failed_ = true;
    }
    buffer_.clear();
    return !failed_;
  }
  uint64_t bytes() const { return bytes_; }
  uint64_t hash() const { return hash_.Digest(); }

 private:
  static constexpr size_t kBufferBytes = 1 << 20;
  void Write(const void* data, size_t size) {
    if (buffer_.size() + size > kBufferBytes) Flush();
    const uint8_t* p = static_cast<const uint8_t*>(data);
    buffer_.insert(buffer_.end(), p, p + size);
    bytes_ += size;
  }
  std::FILE* file_;
  std::vector<uint8_t> buffer_;
  Hash64 hash_;
  uint64_t bytes_ = 0;
  bool failed_ = false;
};

class SnapshotReader {
 public:
  // Reads at most `limit` bytes of `file` from its current position.
  SnapshotReader(std::FILE* file, uint64_t limit) : file_(file), left_in_file_(limit) {}
  template <typename T>
  void load(T& value) {
    if (end_ - next_ >= sizeof(value)) {  // the common case, inlined: a fixed-size copy
      std::memcpy(&value, buffer_.data() + next_, sizeof(value));
      next_ += sizeof(value);
    } else {
      Read(&value, sizeof(value));
    }
  }
  // Bytes of the limit not read.
  uint64_t unread() const { return left_in_file_ + (end_ - next_); }

 private:
  void Read(void* out, size_t size) {
    uint8_t* p = static_cast<uint8_t*>(out);
    while (size > 0) {
      if (next_ == end_) Refill();
      const size_t take = std::min(size, end_ - next_);
      std::memcpy(p, buffer_.data() + next_, take);
      next_ += take;
      p += take;
      size -= take;
    }
  }
  void Refill() {
    const size_t want = static_cast<size_t>(std::min<uint64_t>(buffer_.size(), left_in_file_));
    if (want == 0) throw std::runtime_error("the tree ends before its last node");
    if (std::fread(buffer_.data(), want, 1, file_) != 1) {
      throw std::runtime_error("cannot read the tree");
    }
    left_in_file_ -= want;
    next_ = 0;
    end_ = want;
  }
  std::FILE* file_;
  uint64_t left_in_file_;
  std::vector<uint8_t> buffer_ = std::vector<uint8_t>(1 << 20);
  size_t next_ = 0;
  size_t end_ = 0;
};

}  // namespace

struct DescriptorIndex::Hnsw {
  explicit Hnsw(const DescriptorIndexOptions& options)
      : graph(&space, /*max_elements=*/1024, options.hnsw_links, options.hnsw_build_candidates,
              kHnswSeed) {
    graph.setEf(options.hnsw_search_candidates);
  }
  DescriptorSpace space;
  hnswlib::HierarchicalNSW<int> graph;
};

bool DescriptorIndexOptions::Check(std::string* error) const {
  if (checks < 1) {
    *error = "index checks must be at least 1";
    return false;
  }
  if (hnsw_links < 2 || hnsw_links > 1000 || hnsw_build_candidates < 1 ||
      hnsw_search_candidates < 1) {
    *error = "index hnsw links must be in [2, 1000] and its candidates at least 1";
    return false;
  }
  return true;
}

DescriptorIndex::DescriptorIndex(const DescriptorIndexOptions& options) : options_(options) {}

DescriptorIndex::~DescriptorIndex() = default;

void DescriptorIndex::Add(int32_t owner, const cv::Mat& descriptors) {
  if (descriptors.empty()) return;
  CHECK_EQ(descriptors.type(), CV_8U);
  CHECK_EQ(descriptors.cols, kDescriptorSize);
  cv::Mat block = descriptors.isContinuous() ? descriptors : descriptors.clone();
  const size_t first_point = point_owner_.size();
  for (int r = 0; r < block.rows; ++r) {
    point_owner_.push_back(owner);
    point_row_.push_back(r);
  }
  if (options_.method == DescriptorSearch::kHnsw) {
    AddToHnsw(block, first_point);
  } else {
    blocks_.push_back(block);
    if (!deferred_) AddToTree(block);
  }
}

void DescriptorIndex::DeferInsertion() {
  // FinishDeferred inserts every block from the first: none may be in the tree already.
  CHECK(blocks_.empty()) << "DeferInsertion after Add";
  if (options_.method == DescriptorSearch::kFlann) deferred_ = true;
}

uint64_t DescriptorIndex::ContentDigest(size_t adds) const {
  Hash64 hash;
  size_t point = 0;
  for (size_t b = 0; b < adds; ++b) {
    const cv::Mat& block = blocks_[b];
    const int32_t owner_and_rows[2] = {point_owner_[point], block.rows};
    hash.Update(owner_and_rows, sizeof(owner_and_rows));
    hash.Update(block.data, block.total() * block.elemSize());
    point += block.rows;
  }
  return hash.Digest();
}

SnapshotLoad DescriptorIndex::FinishDeferred(const std::string& snapshot_path) {
  SnapshotLoad result;
  if (!deferred_) {
    // kHnsw, or no DeferInsertion: Add inserted every point already.
    result.message = "nothing deferred: every descriptor was inserted as it was added";
    result.inserted_points = static_cast<int64_t>(size());
    return result;
  }
  deferred_ = false;
  Timer timer;
  size_t first_block = 0;
  if (snapshot_path.empty()) {
    result.message = "no snapshot";
  } else {
    std::string timing;
    StatusOr<size_t> covered = LoadSnapshot(snapshot_path, &timing);
    if (covered.ok()) {
      first_block = *covered;
      result.used = true;
      result.covered_adds = static_cast<int64_t>(first_block);
      result.message = "loaded " + snapshot_path + " (" + std::to_string(first_block) + " of " +
                       std::to_string(blocks_.size()) + " descriptor blocks; " + timing + ")";
      LOG(INFO) << "descriptor index: " << result.message;
    } else {
      tree_.reset();
      result.message = "ignored " + snapshot_path + ": " + covered.status().message();
      // A missing snapshot is the normal first open; anything else is worth a warning.
      if (covered.status().code() == StatusCode::kNotFound) {
        LOG(INFO) << "descriptor index: " << result.message;
      } else {
        LOG(WARNING) << "descriptor index: " << result.message << "; indexing every descriptor";
      }
    }
  }
  result.load_ms = timer.ElapsedMs();
  Timer insert_timer;
  if (first_block < blocks_.size()) {
    if (!tree_) tree_ = std::make_unique<GrownKdTree>();
    tree_->Reserve(point_owner_.size());  // no copy of the nodes while they grow
  }
  for (size_t b = first_block; b < blocks_.size(); ++b) {
    AddToTree(blocks_[b]);
    result.inserted_points += blocks_[b].rows;
  }
  result.insert_ms = insert_timer.ElapsedMs();
  return result;
}

StatusOr<size_t> DescriptorIndex::LoadSnapshot(const std::string& path, std::string* timing) {
  File file(std::fopen(path.c_str(), "rb"));
  if (!file) {
    if (errno == ENOENT) return Status::NotFound("there is none");
    return Status::IoError(std::string("cannot open it: ") + std::strerror(errno));
  }
  uint8_t header_bytes[SnapshotHeader::kBytes];
  if (std::fread(header_bytes, sizeof(header_bytes), 1, file.get()) != 1) {
    return Status::InvalidArgument("it is shorter than its header");
  }
  StatusOr<SnapshotHeader> header = SnapshotHeader::Decode(header_bytes);
  if (!header.ok()) return header.status();
  if (header->adds == 0 || header->adds > blocks_.size()) {
    return Status::InvalidArgument("it covers " + std::to_string(header->adds) +
                                   " descriptor blocks, the map has " +
                                   std::to_string(blocks_.size()));
  }
  const size_t adds = static_cast<size_t>(header->adds);
  size_t points = 0;
  for (size_t b = 0; b < adds; ++b) points += blocks_[b].rows;
  Timer digest_timer;
  const uint64_t digest = header->points == points ? ContentDigest(adds) : 0;
  const double digest_ms = digest_timer.ElapsedMs();
  if (header->points != points || header->content_digest != digest) {
    return Status::InvalidArgument("the map's first " + std::to_string(adds) +
                                   " descriptor blocks are not the ones it covers");
  }
  struct stat info;
  if (fstat(fileno(file.get()), &info) != 0) {
    return Status::IoError(std::string("cannot stat it: ") + std::strerror(errno));
  }
  if (static_cast<uint64_t>(info.st_size) != SnapshotHeader::kBytes + header->payload_bytes) {
    return Status::InvalidArgument("it is " + std::to_string(info.st_size) + " bytes, not " +
                                   std::to_string(SnapshotHeader::kBytes + header->payload_bytes));
  }
  // The whole tree is checked against its hash before any of it is read (reading also checks
  // every index it meets).
  Timer check_timer;
  {
    Hash64 hash;
    std::vector<uint8_t> buffer(1 << 20);
    for (uint64_t left = header->payload_bytes; left > 0;) {
      const size_t want = static_cast<size_t>(std::min<uint64_t>(buffer.size(), left));
      if (std::fread(buffer.data(), want, 1, file.get()) != 1) {
        return Status::IoError("cannot read it");
      }
      hash.Update(buffer.data(), want);
      left -= want;
    }
    if (hash.Digest() != header->payload_hash) {
      return Status::InvalidArgument("its tree is damaged (checksum mismatch)");
    }
  }
  if (std::fseek(file.get(), SnapshotHeader::kBytes, SEEK_SET) != 0) {
    return Status::IoError("cannot read it");
  }
  const double check_ms = check_timer.ElapsedMs();
  Timer tree_timer;
  std::vector<const uint8_t*> point_table;
  point_table.reserve(points);
  for (size_t b = 0; b < adds; ++b) {
    for (int r = 0; r < blocks_[b].rows; ++r) point_table.push_back(blocks_[b].ptr<uint8_t>(r));
  }
  auto tree = std::make_unique<GrownKdTree>();
  SnapshotReader reader(file.get(), header->payload_bytes);
  try {
    tree->Load(std::move(point_table), &reader);
  } catch (const std::exception& e) {
    return Status::InvalidArgument(std::string("its tree cannot be read: ") + e.what());
  }
  if (reader.unread() != 0) {
    return Status::InvalidArgument("its tree is followed by " + std::to_string(reader.unread()) +
                                   " stray bytes");
  }
  tree_ = std::move(tree);
  std::ostringstream text;
  text.precision(3);
  text << "digest " << digest_ms / 1000 << " s, checksum " << check_ms / 1000 << " s, tree "
       << tree_timer.ElapsedMs() / 1000 << " s";
  *timing = text.str();
  return adds;
}

Status DescriptorIndex::SaveSnapshot(const std::string& path) const {
  if (options_.method != DescriptorSearch::kFlann) {
    return Status::InvalidArgument("only the FLANN descriptor index has snapshots");
  }
  CHECK(!deferred_) << "SaveSnapshot between DeferInsertion and FinishDeferred";
  if (!tree_) return Status::InvalidArgument("the descriptor index is empty: nothing to save");
  // One fixed name: a file left by a process killed while writing is overwritten by the next
  // save rather than piling up. A save holds a lock on it while writing: a second process that
  // saves at the same moment (a server stopping while `placerec-map index` runs) is refused
  // rather than writing into it.
  const std::string temporary = path + ".tmp";
  const int fd = open(temporary.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return Status::IoError("cannot write " + temporary + ": " + std::strerror(errno));
  File file(fdopen(fd, "wb"));
  if (!file) {
    close(fd);
    return Status::IoError("cannot write " + temporary + ": " + std::strerror(errno));
  }
  struct stat held, named;
  if (flock(fd, LOCK_EX | LOCK_NB) != 0 || fstat(fd, &held) != 0 ||
      stat(temporary.c_str(), &named) != 0 || held.st_ino != named.st_ino ||
      held.st_dev != named.st_dev) {
    // Locked by another save, or renamed by one that finished since this one opened it.
    return Status::IoError("another process is writing " + temporary + ": try again");
  }
  if (ftruncate(fd, 0) != 0) {
    return Status::IoError("cannot write " + temporary + ": " + std::strerror(errno));
  }
  auto fail = [&](const std::string& what) {
    const std::string reason = std::strerror(errno);
    file.reset();
    std::remove(temporary.c_str());
    return Status::IoError("cannot write " + temporary + ": " + what + ": " + reason);
  };
  SnapshotHeader header;
  header.adds = blocks_.size();
  header.points = point_owner_.size();
  header.content_digest = ContentDigest(blocks_.size());
  // The header is written last, once the payload's size and hash are known.
  std::vector<uint8_t> placeholder(SnapshotHeader::kBytes, 0);
  if (std::fwrite(placeholder.data(), placeholder.size(), 1, file.get()) != 1) {
    return fail("header");
  }
  SnapshotWriter writer(file.get());
  tree_->Save(&writer);
  if (!writer.Flush()) return fail("tree");
  header.payload_bytes = writer.bytes();
  header.payload_hash = writer.hash();
  const std::vector<uint8_t> bytes = header.Encode();
  if (std::fseek(file.get(), 0, SEEK_SET) != 0 ||
      std::fwrite(bytes.data(), bytes.size(), 1, file.get()) != 1) {
    return fail("header");
  }
  if (std::fflush(file.get()) != 0 || fsync(fileno(file.get())) != 0) return fail("flush");
  if (std::fclose(file.release()) != 0) return fail("close");
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::remove(temporary.c_str());
    return Status::IoError("cannot rename " + temporary + " to " + path + ": " + reason);
  }
  return Status::Ok();
}

void DescriptorIndex::AddToTree(const cv::Mat& block) {
  if (!tree_) tree_ = std::make_unique<GrownKdTree>();
  for (int r = 0; r < block.rows; ++r) tree_->Add(block.ptr<uint8_t>(r));
}

void DescriptorIndex::AddToHnsw(const cv::Mat& block, size_t first_point) {
  if (!hnsw_) hnsw_ = std::make_unique<Hnsw>(options_);
  hnswlib::HierarchicalNSW<int>& graph = hnsw_->graph;
  const size_t needed = first_point + block.rows;
  if (needed > graph.max_elements_) {
    // The graph copies the descriptors; doubling keeps the copies rare.
    graph.resizeIndex(std::max(needed, 2 * graph.max_elements_));
  }
  for (int r = 0; r < block.rows; ++r) graph.addPoint(block.ptr<uint8_t>(r), first_point + r);
}

void DescriptorIndex::Search(const cv::Mat& queries, int knn,
                             std::vector<std::vector<Neighbour>>* neighbours) const {
  CHECK(!deferred_) << "Search between DeferInsertion and FinishDeferred";
  neighbours->assign(queries.rows, {});
  if (size() == 0 || queries.empty() || knn <= 0) return;
  CHECK_EQ(queries.type(), CV_8U);
  CHECK_EQ(queries.cols, kDescriptorSize);
  const cv::Mat query_block = queries.isContinuous() ? queries : queries.clone();
  const size_t k = std::min<size_t>(knn, size());
  if (options_.method == DescriptorSearch::kHnsw) {
    for (int q = 0; q < query_block.rows; ++q) {
      // Farthest first.
      std::priority_queue<std::pair<int, hnswlib::labeltype>> found =
          hnsw_->graph.searchKnn(query_block.ptr<uint8_t>(q), k);
      std::vector<Neighbour>& out = (*neighbours)[q];
      out.resize(found.size());
      for (size_t j = found.size(); j-- > 0; found.pop()) {
        const size_t point = found.top().second;
        out[j] = {point_owner_[point], point_row_[point], static_cast<float>(found.top().first)};
      }
    }
    return;
  }
  std::vector<std::vector<GrownKdTree::Found>> found;
  tree_->SearchMany(query_block.data, query_block.rows, query_block.step, static_cast<int>(k),
                    options_.checks, &found);
  for (int q = 0; q < query_block.rows; ++q) {
    std::vector<Neighbour>& out = (*neighbours)[q];
    out.reserve(found[q].size());
    for (const GrownKdTree::Found& f : found[q]) {
      out.push_back({point_owner_[f.point], point_row_[f.point], f.distance});
    }
  }
}

}  // namespace placerec
