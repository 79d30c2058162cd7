// Integration test of the job API: starts the real reconduit-server binary on a free port with
// a temporary data folder and speaks HTTP to it. Jobs are finished (or claimed) through the
// JobStore directly, standing in for a worker.
#include "core/io/file_util.h"
#include "server/http/test_client.h"
#include "tests/long_test_util.h"
#include "tests/server_process.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sqlite3.h>
#include <zip.h>

#include "store/job_store.h"
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using server::Fetch;
using server::TestClient;
using server::TestResponse;
using testing_util::ServerProcess;

using Headers = std::vector<std::pair<std::string, std::string>>;
constexpr char kBoundary[] = "reconduit-test-boundary-7d1f";
constexpr char kWorker[] = "api-test-worker";

nlohmann::json Json(const TestResponse& response) {
  return nlohmann::json::parse(response.body, nullptr, /*allow_exceptions=*/false);
}

std::string ErrorMessage(const TestResponse& response) {
  const nlohmann::json json = Json(response);
  if (!json.is_object() || !json.contains("error")) return "";
  return json["error"].value("message", "");
}

std::string ReadFileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

struct Part {
  std::string name;
  std::optional<std::string> filename;
  std::string data;
};

std::string Multipart(const std::vector<Part>& parts) {
  std::string body;
  for (const Part& part : parts) {
    body += std::string("--") + kBoundary + "\r\nContent-Disposition: form-data; name=\"" +
            part.name + "\"";
    if (part.filename) body += "; filename=\"" + *part.filename + "\"";
    body += "\r\nContent-Type: application/octet-stream\r\n\r\n" + part.data + "\r\n";
  }
  return body + "--" + kBoundary + "--\r\n";
}

Headers MultipartHeaders(Headers extra = {}) {
  extra.emplace_back("Content-Type", std::string("multipart/form-data; boundary=") + kBoundary);
  return extra;
}

// A textured synthetic photo as JPEG (deterministic).
std::string SyntheticJpeg(int width = 320, int height = 240, int seed = 1) {
  cv::Mat image(height, width, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, 255);
  std::vector<unsigned char> bytes;
  cv::imencode(".jpg", image, bytes, {cv::IMWRITE_JPEG_QUALITY, 90});
  return std::string(bytes.begin(), bytes.end());
}

struct ZipEntry {
  std::string name;
  std::string data;
};

std::string MakeZip(const fs::path& path, const std::vector<ZipEntry>& entries) {
  int error = 0;
  zip_t* zip = zip_open(path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
  EXPECT_NE(zip, nullptr);
  if (zip == nullptr) return "";
  for (const ZipEntry& entry : entries) {
    zip_source_t* source = zip_source_buffer(zip, entry.data.data(), entry.data.size(), 0);
    EXPECT_GE(zip_file_add(zip, entry.name.c_str(), source, ZIP_FL_ENC_UTF_8), 0);
  }
  EXPECT_EQ(zip_close(zip), 0);
  return ReadFileBytes(path);
}

fs::path TempleImages() {
  const char* root = std::getenv("RECONDUIT_SOURCE_DIR");
  return fs::path(root != nullptr ? root : ".") / ".." / "shared" / "datasets" /
         "templeSparseRing" / "images";
}

class ApiTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("reconduit_api_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    server_.reset();
    store_.reset();
    fs::remove_all(dir_);
  }

  fs::path data() const { return dir_ / "data"; }

  // Starts a server on the test's data folder with extra flags; with `file_size_limit` > 0
  // under that RLIMIT_FSIZE (prlimit): no file it writes may grow past it, as on a full disk.
  // `wrapper` (a program and its arguments, e.g. unshare) runs the server's command line as its
  // last arguments.
  void StartServer(const std::vector<std::string>& extra = {},
                   std::int64_t file_size_limit = 0,
                   std::vector<std::string> wrapper = {}) {
    if (file_size_limit > 0) {
      wrapper.insert(wrapper.end(),
                     {"/usr/bin/prlimit", "--fsize=" + std::to_string(file_size_limit)});
    }
    server_ = std::make_unique<ServerProcess>(wrapper.empty() ? RECONDUIT_SERVER_BINARY
                                                              : wrapper.front());
    std::vector<std::string> args;
    if (!wrapper.empty()) {
      args.assign(wrapper.begin() + 1, wrapper.end());
      args.push_back(RECONDUIT_SERVER_BINARY);
    }
    args.insert(args.end(), {"--port", "0", "--data", data().string(), "--threads", "2", "--web",
                             (dir_ / "no-web").string()});
    args.insert(args.end(), extra.begin(), extra.end());
    ASSERT_TRUE(server_->Start(args, dir_ / "stderr.txt")) << server_->error();
    port_ = server_->port();
  }

  JobStore& Store() {
    if (!store_) {
      Result<std::unique_ptr<JobStore>> store =
          OpenSqliteJobStore((data() / "reconduit.db").string());
      THROW_CHECK(store.ok()) << store.status();
      store_ = std::move(store.value());
    }
    return *store_;
  }

  TestResponse Upload(const std::vector<Part>& parts, Headers extra = {}) {
    return Fetch(port_, "POST", "/api/v1/jobs", MultipartHeaders(std::move(extra)),
                 Multipart(parts));
  }

  // Uploads two synthetic photos; returns the job id.
  std::string UploadJob() {
    const TestResponse response = Upload({{"images", "a.jpg", SyntheticJpeg(320, 240, 1)},
                                          {"images", "b.jpg", SyntheticJpeg(320, 240, 2)}});
    EXPECT_EQ(response.status, 201u) << response.body;
    return Json(response).value("id", "");
  }

  std::vector<fs::path> TempEntries() const {
    std::vector<fs::path> entries;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(data() / "tmp", ec)) {
      entries.push_back(entry.path());
    }
    return entries;
  }

  fs::path dir_;
  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<JobStore> store_;
  int port_ = 0;
};

TEST_F(ApiTest, UploadsATempleSetAndServesStatusEventsListOptionsAndMetrics) {
  const fs::path images = TempleImages();
  if (!fs::is_directory(images)) {
    GTEST_SKIP() << "dataset absent: " << images << " (needs ../shared/datasets/templeSparseRing)";
  }
  StartServer();
  const std::vector<std::string> names = {"templeSR0001.png", "templeSR0002.png",
                                          "templeSR0003.png"};
  std::vector<Part> parts;
  for (const std::string& name : names) {
    parts.push_back({"images", name, ReadFileBytes(images / name)});
  }
  parts[2].filename = "../../etc/evil.png";  // Display-only; stored as 0003.png.
  parts.push_back({"options", std::nullopt, R"({"max_features": 4000})"});

  const TestResponse created = Upload(parts);
  ASSERT_EQ(created.status, 201u) << created.body;
  const nlohmann::json job = Json(created);
  const std::string id = job["id"];
  EXPECT_TRUE(IsValidJobId(id));
  EXPECT_EQ(created.Header("Location"), "/api/v1/jobs/" + id);
  EXPECT_EQ(job["state"], "queued");
  EXPECT_EQ(job["options"]["max_features"], 4000);
  EXPECT_EQ(job["images"]["accepted"], 3);
  EXPECT_EQ(job["images"]["items"][2]["name"], "evil.png");

  // The rows, as a worker will see them.
  Result<std::vector<JobImageRecord>> rows = Store().ListImages(id);
  ASSERT_TRUE(rows.ok()) << rows.status();
  ASSERT_EQ(rows->size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const JobImageRecord& row = (*rows)[i];
    EXPECT_EQ(row.index, i);
    EXPECT_EQ(row.stored_name, "000" + std::to_string(i + 1) + ".png");
    EXPECT_TRUE(row.photo.accepted);
    EXPECT_EQ(row.photo.width, 640);
    EXPECT_EQ(row.photo.height, 480);
    EXPECT_EQ(row.photo.bytes, static_cast<std::int64_t>(fs::file_size(images / names[i])));
    EXPECT_EQ(ReadFileBytes(data() / "jobs" / id / "input" / row.stored_name),
              ReadFileBytes(images / names[i]));
  }
  EXPECT_EQ((*rows)[0].original_name, "templeSR0001.png");
  EXPECT_EQ((*rows)[2].original_name, "evil.png");
  EXPECT_FALSE(fs::exists(data() / "etc"));
  EXPECT_TRUE(TempEntries().empty());

  const TestResponse status = Fetch(port_, "GET", "/api/v1/jobs/" + id);
  ASSERT_EQ(status.status, 200u);
  const nlohmann::json status_json = Json(status);
  EXPECT_EQ(status_json["state"], "queued");
  EXPECT_EQ(status_json["counts"]["images"], 3);
  EXPECT_EQ(status_json["links"]["events"], "/api/v1/jobs/" + id + "/events");
  EXPECT_EQ(status_json["images"]["items"].size(), 3u);

  const TestResponse events = Fetch(port_, "GET", "/api/v1/jobs/" + id + "/events?after=0");
  ASSERT_EQ(events.status, 200u);
  EXPECT_EQ(events.Header("Content-Type"), "application/x-ndjson");
  const nlohmann::json first = nlohmann::json::parse(events.body.substr(0, events.body.find('\n')));
  EXPECT_EQ(first["level"], "info");
  const std::string last = events.Header("X-Last-Event-Id");
  EXPECT_EQ(last, std::to_string(first["id"].get<std::int64_t>()));
  EXPECT_EQ(Fetch(port_, "GET", "/api/v1/jobs/" + id + "/events?after=" + last).body, "");
  EXPECT_EQ(Fetch(port_, "GET", "/api/v1/jobs/" + id + "/events?limit=0").status, 400u);

  const TestResponse list = Fetch(port_, "GET", "/api/v1/jobs?limit=10&offset=0&state=queued");
  ASSERT_EQ(list.status, 200u);
  EXPECT_EQ(Json(list)["total"], 1);
  EXPECT_EQ(Json(list)["jobs"][0]["id"], id);
  EXPECT_EQ(Json(Fetch(port_, "GET", "/api/v1/jobs?state=failed"))["total"], 0);
  EXPECT_EQ(Fetch(port_, "GET", "/api/v1/jobs?state=bogus").status, 400u);

  const TestResponse options = Fetch(port_, "GET", "/api/v1/options");
  ASSERT_EQ(options.status, 200u);
  bool has_min_side = false;
  const nlohmann::json options_json = Json(options);
  for (const auto& option : options_json["options"]) {
    has_min_side |= option["name"] == "min_image_side";
  }
  EXPECT_TRUE(has_min_side) << options.body;
  EXPECT_TRUE(options_json["limits"].contains("max_photos"));

  // Unknown and malformed ids.
  for (const std::string& bad : {std::string(32, '0'), std::string("nope"), std::string("..")}) {
    const TestResponse missing = Fetch(port_, "GET", "/api/v1/jobs/" + bad);
    EXPECT_EQ(missing.status, 404u) << bad;
    EXPECT_EQ(Json(missing)["error"]["code"], "not_found");
  }

  // Server-Sent Events: a queued job streams its events; canceling it ends the stream.
  TestClient sse(port_);
  ASSERT_TRUE(sse.Write("GET /api/v1/jobs/" + id +
                        "/events HTTP/1.1\r\nHost: x\r\nAccept: text/event-stream\r\n\r\n"));
  std::this_thread::sleep_for(300ms);
  ASSERT_EQ(Fetch(port_, "POST", "/api/v1/jobs/" + id + "/cancel").status, 200u);
  const TestResponse stream = sse.Read();
  ASSERT_EQ(stream.status, 200u) << stream.error;
  EXPECT_EQ(stream.Header("Content-Type").rfind("text/event-stream", 0), 0u);
  EXPECT_NE(stream.body.find("id: " + last + "\ndata: {"), std::string::npos) << stream.body;
  EXPECT_NE(stream.body.find("canceled"), std::string::npos) << stream.body;
  EXPECT_NE(stream.body.find("event: end\ndata: {\"id\":\"" + id + "\",\"state\":\"canceled\"}"),
            std::string::npos)
      << stream.body;

  const TestResponse metrics = Fetch(port_, "GET", "/metrics");
  ASSERT_EQ(metrics.status, 200u);
  EXPECT_NE(metrics.body.find("reconduit_jobs{state=\"canceled\"} 1"), std::string::npos)
      << metrics.body;
  EXPECT_NE(metrics.body.find("reconduit_queue_length 0"), std::string::npos);
  EXPECT_NE(metrics.body.find("reconduit_http_requests_total{code=\"201\"} 1"), std::string::npos);
  EXPECT_NE(metrics.body.find("reconduit_http_requests_total{code=\"404\"} 3"), std::string::npos);
  EXPECT_NE(metrics.body.find("reconduit_upload_bytes_total "), std::string::npos);
  EXPECT_EQ(metrics.body.find("reconduit_upload_bytes_total 0\n"), std::string::npos);

  EXPECT_EQ(server_->Terminate(10s), 0) << server_->Stderr();
}

TEST_F(ApiTest, RefusesBadInputWithTheRightStatusAndLeavesNothingBehind) {
  StartServer({"--max-upload-bytes", "1500000", "--max-photos", "4"});
  const std::string good = SyntheticJpeg(320, 240, 7);
  int created = 0;

  // A part that is not an image: 415 naming the file.
  TestResponse response =
      Upload({{"images", "a.jpg", good}, {"images", "notes.txt", "hello, I am text"}});
  EXPECT_EQ(response.status, 415u) << response.body;
  EXPECT_NE(ErrorMessage(response).find("notes.txt"), std::string::npos) << response.body;

  // A truncated JPEG next to a good one: accepted job, the truncated photo listed as rejected.
  const std::string truncated = good.substr(0, good.size() / 2);
  response = Upload({{"images", "good.jpg", good}, {"images", "cut.jpg", truncated}});
  ASSERT_EQ(response.status, 201u) << response.body;
  ++created;
  const nlohmann::json items = Json(response)["images"]["items"];
  EXPECT_EQ(items[0]["status"], "accepted");
  EXPECT_EQ(items[1]["status"], "rejected");
  EXPECT_EQ(items[1]["name"], "cut.jpg");
  EXPECT_NE(items[1]["reason"].get<std::string>().find("truncated"), std::string::npos) << items[1];
  EXPECT_EQ(Json(response)["counts"]["images"], 1);

  // Only truncated photos: 400 listing the reason.
  response = Upload({{"images", "cut.jpg", truncated}});
  EXPECT_EQ(response.status, 400u);
  EXPECT_NE(ErrorMessage(response).find("cut.jpg: truncated"), std::string::npos) << response.body;

  // Corrupt compressed data between an intact header and end marker: uploads are checked from
  // their headers only (no decoding on an HTTP I/O thread), so the photo is accepted here; the
  // ingest stage decodes it and refuses it (core/image/image_check_test.cc).
  std::string scrambled = good;
  for (std::size_t i = good.size() / 2; i < good.size() / 2 + 64; ++i) scrambled[i] = '\0';
  response = Upload({{"images", "good.jpg", good}, {"images", "scrambled.jpg", scrambled}});
  ASSERT_EQ(response.status, 201u) << response.body;
  ++created;
  EXPECT_EQ(Json(response)["images"]["items"][1]["status"], "accepted") << response.body;

  // Over the size limit: announced (413 before the body) and chunked (413 while streaming).
  const std::string big(1600000, 'x');
  response = Upload({{"images", "big.jpg", "\xff\xd8\xff" + big}});
  EXPECT_EQ(response.status, 413u);
  {
    TestClient client(port_);
    const std::string body = Multipart({{"images", "big.jpg", "\xff\xd8\xff" + big}});
    std::ostringstream chunk_size;
    chunk_size << std::hex << body.size();
    ASSERT_TRUE(client.Write(std::string("POST /api/v1/jobs HTTP/1.1\r\nHost: x\r\n") +
                             "Content-Type: multipart/form-data; boundary=" + kBoundary +
                             "\r\nTransfer-Encoding: chunked\r\n\r\n" + chunk_size.str() + "\r\n" +
                             body + "\r\n0\r\n\r\n"));
    const TestResponse chunked = client.Read();
    EXPECT_EQ(chunked.status, 413u) << chunked.error;
  }

  // Too many photos for one job.
  response = Upload({{"images", "1.jpg", good},
                     {"images", "2.jpg", good},
                     {"images", "3.jpg", good},
                     {"images", "4.jpg", good},
                     {"images", "5.jpg", good}});
  EXPECT_EQ(response.status, 413u);
  EXPECT_EQ(Json(response)["error"]["code"], "too_many_photos");

  // Options: malformed JSON, out of range, unknown name; each names the problem.
  response = Upload({{"images", "a.jpg", good}, {"options", std::nullopt, "{\"max_features\": "}});
  EXPECT_EQ(response.status, 400u);
  EXPECT_NE(ErrorMessage(response).find("options"), std::string::npos) << response.body;
  EXPECT_NE(ErrorMessage(response).find("not valid JSON"), std::string::npos) << response.body;
  response =
      Upload({{"images", "a.jpg", good}, {"options", std::nullopt, R"({"min_image_side": 3})"}});
  EXPECT_EQ(response.status, 400u);
  EXPECT_NE(ErrorMessage(response).find("min_image_side"), std::string::npos) << response.body;
  response =
      Upload({{"options", std::nullopt, R"({"no_such_option": 1})"}, {"images", "a.jpg", good}});
  EXPECT_EQ(response.status, 400u);
  EXPECT_NE(ErrorMessage(response).find("no_such_option"), std::string::npos) << response.body;
  response = Fetch(port_, "POST", "/api/v1/jobs?options=%7B%22max_features%22%3A1%7D",
                   MultipartHeaders(), Multipart({{"images", "a.jpg", good}}));
  EXPECT_EQ(response.status, 400u);
  EXPECT_NE(ErrorMessage(response).find("max_features"), std::string::npos) << response.body;

  // No photo, an unexpected field, a body that is neither multipart nor zip.
  EXPECT_EQ(Upload({{"options", std::nullopt, "{}"}}).status, 400u);
  EXPECT_EQ(Upload({{"photo", "a.jpg", good}}).status, 400u);
  EXPECT_EQ(Fetch(port_, "POST", "/api/v1/jobs", {{"Content-Type", "text/plain"}}, "hi").status,
            415u);

  // File names are display-only: an absolute or ../ name is stored under a generated name.
  response = Upload({{"images", "/etc/passwd", good}, {"images", "..\\..\\win.jpg", good}});
  ASSERT_EQ(response.status, 201u) << response.body;
  ++created;
  const std::string id = Json(response)["id"];
  EXPECT_EQ(Json(response)["images"]["items"][0]["name"], "passwd");
  EXPECT_EQ(Json(response)["images"]["items"][1]["name"], "win.jpg");
  EXPECT_TRUE(fs::is_regular_file(data() / "jobs" / id / "input" / "0001.jpg"));
  EXPECT_TRUE(fs::is_regular_file(data() / "jobs" / id / "input" / "0002.jpg"));

  // Zip bodies: a good one, one with a ../ entry, a bomb, one with a non-image.
  const Headers zip_headers = {{"Content-Type", "application/zip"}};
  response =
      Fetch(port_, "POST", "/api/v1/jobs?options=%7B%22max_features%22%3A2048%7D", zip_headers,
            MakeZip(dir_ / "good.zip", {{"set/a.jpg", good}, {"set/b.jpg", good}}));
  ASSERT_EQ(response.status, 201u) << response.body;
  ++created;
  EXPECT_EQ(Json(response)["images"]["accepted"], 2);
  EXPECT_EQ(Json(response)["options"]["max_features"], 2048);
  response = Fetch(port_, "POST", "/api/v1/jobs", zip_headers,
                   MakeZip(dir_ / "evil.zip", {{"a.jpg", good}, {"../../evil.jpg", good}}));
  EXPECT_EQ(response.status, 400u);
  EXPECT_NE(ErrorMessage(response).find("../../evil.jpg"), std::string::npos) << response.body;
  EXPECT_FALSE(fs::exists(data() / "evil.jpg"));
  EXPECT_FALSE(fs::exists(dir_ / "evil.jpg"));
  response = Fetch(
      port_, "POST", "/api/v1/jobs", zip_headers,
      MakeZip(dir_ / "bomb.zip", {{"bomb.jpg", "\xff\xd8\xff" + std::string(64 << 20, '\0')}}));
  EXPECT_EQ(response.status, 413u) << response.body;
  EXPECT_NE(ErrorMessage(response).find("bomb"), std::string::npos) << response.body;
  response = Fetch(port_, "POST", "/api/v1/jobs", zip_headers,
                   MakeZip(dir_ / "text.zip", {{"a.jpg", good}, {"readme.txt", "text"}}));
  EXPECT_EQ(response.status, 415u);
  EXPECT_NE(ErrorMessage(response).find("readme.txt"), std::string::npos) << response.body;
  // What Windows and macOS put in zips is skipped and listed (issue 12), not refused.
  response = Fetch(port_, "POST", "/api/v1/jobs", zip_headers,
                   MakeZip(dir_ / "real.zip", {{"set/a.jpg", good},
                                               {"set/Thumbs.db", "thumbnails"},
                                               {"set/.DS_Store", "finder"},
                                               {"__MACOSX/set/._a.jpg", "fork"},
                                               {"set/older.zip", "PK\x03\x04"}}));
  ASSERT_EQ(response.status, 201u) << response.body;
  ++created;
  EXPECT_EQ(Json(response)["images"]["accepted"], 1);
  EXPECT_EQ(Json(response)["skipped"],
            (nlohmann::json{"Thumbs.db", ".DS_Store", "._a.jpg", "older.zip"}));

  // Every 400 says bad_request, query parameters too; a malformed multipart body says so once.
  response = Fetch(port_, "GET", "/api/v1/jobs?limit=0");
  EXPECT_EQ(response.status, 400u);
  EXPECT_EQ(Json(response)["error"]["code"], "bad_request");
  response = Fetch(port_, "POST", "/api/v1/jobs", MultipartHeaders(),
                   "--" + std::string(kBoundary) + "\r\nno colon here\r\n\r\nx\r\n");
  EXPECT_EQ(response.status, 400u);
  const std::string message = ErrorMessage(response);
  EXPECT_NE(message.find("malformed multipart body"), std::string::npos) << message;
  EXPECT_EQ(message.find("malformed multipart body"), message.rfind("malformed multipart body"))
      << message;

  // Nothing else disturbed: exactly the accepted uploads became jobs; no temporary files.
  EXPECT_EQ(Json(Fetch(port_, "GET", "/api/v1/jobs"))["total"], created);
  std::this_thread::sleep_for(100ms);
  EXPECT_TRUE(TempEntries().empty());
  int job_dirs = 0;
  for (const auto& entry : fs::directory_iterator(data() / "jobs"))
    job_dirs += entry.is_directory();
  EXPECT_EQ(job_dirs, created);
  EXPECT_EQ(Fetch(port_, "GET", "/healthz").status, 200u);
}

TEST_F(ApiTest, RequiresTheBearerTokenWhenConfigured) {
  StartServer({"--token", "s3cret"});
  const std::string body = Multipart({{"images", "a.jpg", SyntheticJpeg()}});
  for (const Headers& auth : {Headers{}, Headers{{"Authorization", "Bearer wrong"}}}) {
    Headers headers = MultipartHeaders(auth);
    const TestResponse upload = Fetch(port_, "POST", "/api/v1/jobs", headers, body);
    EXPECT_EQ(upload.status, 401u);
    EXPECT_EQ(Json(upload)["error"]["code"], "unauthorized");
    EXPECT_EQ(Fetch(port_, "GET", "/api/v1/jobs", auth).status, 401u);
    EXPECT_EQ(Fetch(port_, "GET", "/metrics", auth).status, 401u);
  }
  const Headers ok = {{"Authorization", "Bearer s3cret"}};
  EXPECT_EQ(Fetch(port_, "POST", "/api/v1/jobs", MultipartHeaders(ok), body).status, 201u);
  EXPECT_EQ(Json(Fetch(port_, "GET", "/api/v1/jobs", ok))["total"], 1);
}

TEST_F(ApiTest, AFullQueueAnswers503WithRetryAfter) {
  StartServer({"--max-queued-jobs", "1", "--retry-after", "7"});
  ASSERT_FALSE(UploadJob().empty());
  const TestResponse full = Upload({{"images", "a.jpg", SyntheticJpeg()}});
  EXPECT_EQ(full.status, 503u) << full.body << full.error << "\n" << server_->Stderr();
  EXPECT_EQ(full.Header("Retry-After"), "7");
  EXPECT_NE(ErrorMessage(full).find("queue is full"), std::string::npos) << full.body;
  EXPECT_EQ(Json(Fetch(port_, "GET", "/api/v1/jobs"))["total"], 1);
}

TEST_F(ApiTest, ServesResultsAndEnforcesTheJobStates) {
  StartServer();
  const std::string id = UploadJob();
  ASSERT_FALSE(id.empty());
  EXPECT_EQ(Fetch(port_, "GET", "/api/v1/jobs/" + id + "/result.zip").status, 409u);

  // Stand in for a worker: claim, write the results, finish.
  Result<std::optional<Job>> claimed = Store().ClaimNextJob(kWorker, 60s);
  ASSERT_TRUE(claimed.ok() && claimed->has_value());
  EXPECT_EQ(Fetch(port_, "DELETE", "/api/v1/jobs/" + id).status, 409u);  // Running.
  std::string zip_bytes(10000, '\0');
  std::mt19937 random(3);
  for (char& c : zip_bytes) c = static_cast<char>(random());
  const fs::path job_dir = data() / "jobs" / id;
  std::ofstream(job_dir / "result.zip", std::ios::binary) << zip_bytes;
  fs::create_directories(job_dir / "output" / "report");
  std::ofstream(job_dir / "output" / "model.glb", std::ios::binary) << "glTF....";
  std::ofstream(job_dir / "output" / "report" / "similarity.png", std::ios::binary) << "png!";
  const std::string sha = Sha256Hex(zip_bytes);
  ASSERT_TRUE(Store().FinishSucceeded(id, kWorker, {10000, sha, {}}).ok());

  const std::string base = "/api/v1/jobs/" + id;
  const TestResponse whole = Fetch(port_, "GET", base + "/result.zip");
  ASSERT_EQ(whole.status, 200u);
  EXPECT_EQ(whole.body, zip_bytes);
  EXPECT_EQ(whole.Header("ETag"), "\"" + sha + "\"");
  EXPECT_EQ(whole.Header("Content-Type"), "application/zip");
  EXPECT_EQ(whole.Header("Accept-Ranges"), "bytes");
  EXPECT_EQ(
      Fetch(port_, "GET", base + "/result.zip", {{"If-None-Match", "\"" + sha + "\""}}).status,
      304u);
  EXPECT_EQ(Fetch(port_, "GET", base + "/result.zip", {{"If-None-Match", "\"other\""}}).status,
            200u);
  const TestResponse part = Fetch(port_, "GET", base + "/result.zip", {{"Range", "bytes=100-199"}});
  ASSERT_EQ(part.status, 206u);
  EXPECT_EQ(part.body, zip_bytes.substr(100, 100));
  EXPECT_EQ(part.Header("Content-Range"), "bytes 100-199/10000");
  const TestResponse tail = Fetch(port_, "GET", base + "/result.zip", {{"Range", "bytes=-10"}});
  ASSERT_EQ(tail.status, 206u);
  EXPECT_EQ(tail.body, zip_bytes.substr(9990));
  const TestResponse outside =
      Fetch(port_, "GET", base + "/result.zip", {{"Range", "bytes=20000-"}});
  EXPECT_EQ(outside.status, 416u);
  EXPECT_EQ(outside.Header("Content-Range"), "bytes */10000");
  // If-Range with the current tag made weak: the whole file (strong comparison only).
  const TestResponse weak = Fetch(port_, "GET", base + "/result.zip",
                                  {{"Range", "bytes=0-9"}, {"If-Range", "W/\"" + sha + "\""}});
  EXPECT_EQ(weak.status, 200u);
  EXPECT_EQ(weak.body.size(), zip_bytes.size());
  // If-Range with a stale tag: the whole file.
  EXPECT_EQ(
      Fetch(port_, "GET", base + "/result.zip", {{"Range", "bytes=0-9"}, {"If-Range", "\"stale\""}})
          .status,
      200u);

  const TestResponse files = Fetch(port_, "GET", base + "/files");
  ASSERT_EQ(files.status, 200u);
  ASSERT_EQ(Json(files)["files"].size(), 2u);
  EXPECT_EQ(Json(files)["files"][0]["name"], "model.glb");
  EXPECT_EQ(Json(files)["files"][1]["name"], "report/similarity.png");
  const TestResponse glb = Fetch(port_, "GET", base + "/files/model.glb");
  EXPECT_EQ(glb.status, 200u);
  EXPECT_EQ(glb.Header("Content-Type"), "model/gltf-binary");
  EXPECT_EQ(glb.body, "glTF....");
  const TestResponse png = Fetch(port_, "GET", base + "/files/report/similarity.png");
  EXPECT_EQ(png.status, 200u);
  EXPECT_EQ(png.Header("Content-Type"), "image/png");
  EXPECT_EQ(Fetch(port_, "GET", base + "/files/nope.txt").status, 404u);
  for (const char* escape : {"/files/../result.zip", "/files/..%2Fresult.zip", "/files/%2e%2e/x",
                             "/files/report/../../input/0001.jpg"}) {
    const TestResponse refused = Fetch(port_, "GET", base + escape);
    EXPECT_TRUE(refused.status == 400u || refused.status == 404u)
        << escape << " " << refused.status;
    EXPECT_NE(refused.body, zip_bytes);
  }

  // A finished job cannot be canceled, nor restarted unless failed or canceled.
  const TestResponse cancel = Fetch(port_, "POST", base + "/cancel");
  EXPECT_EQ(cancel.status, 409u);
  EXPECT_NE(ErrorMessage(cancel).find("succeeded"), std::string::npos);
  EXPECT_EQ(Fetch(port_, "POST", base + "/restart").status, 409u);

  // A running job: cancel requests the stop; a failed job restarts.
  const std::string second = UploadJob();
  ASSERT_TRUE(Store().ClaimNextJob(kWorker, 60s).ok());
  const TestResponse cancel_running = Fetch(port_, "POST", "/api/v1/jobs/" + second + "/cancel");
  ASSERT_EQ(cancel_running.status, 200u);
  EXPECT_EQ(Json(cancel_running)["state"], "running");
  EXPECT_EQ(Json(cancel_running)["cancel_requested"], true);
  ASSERT_TRUE(Store().FinishFailed(second, kWorker, "no geometry", "sparse").ok());
  const TestResponse failed = Fetch(port_, "GET", "/api/v1/jobs/" + second);
  EXPECT_EQ(Json(failed)["state"], "failed");
  EXPECT_EQ(Json(failed)["error"]["message"], "no geometry");
  EXPECT_EQ(Json(failed)["error"]["stage"], "sparse");
  const TestResponse restarted = Fetch(port_, "POST", "/api/v1/jobs/" + second + "/restart");
  ASSERT_EQ(restarted.status, 200u);
  EXPECT_EQ(Json(restarted)["state"], "queued");

  // SSE on a final job: every event, then "end".
  const TestResponse stream =
      Fetch(port_, "GET", base + "/events", {{"Accept", "text/event-stream"}});
  ASSERT_EQ(stream.status, 200u);
  EXPECT_NE(stream.body.find("event: end\ndata: {\"id\":\"" + id + "\",\"state\":\"succeeded\"}"),
            std::string::npos)
      << stream.body;

  // Delete removes the rows, then the folder.
  const TestResponse deleted = Fetch(port_, "DELETE", base);
  EXPECT_EQ(deleted.status, 200u);
  EXPECT_FALSE(fs::exists(job_dir));
  EXPECT_EQ(Fetch(port_, "GET", base).status, 404u);
  EXPECT_EQ(Fetch(port_, "DELETE", base).status, 404u);

  const std::string metrics = Fetch(port_, "GET", "/metrics").body;
  EXPECT_NE(metrics.find("reconduit_http_requests_total{code=\"206\"} 2"), std::string::npos)
      << metrics;
  EXPECT_NE(metrics.find("reconduit_http_requests_total{code=\"409\"}"), std::string::npos);
}

TEST_F(ApiTest, KillDuringUploadLeavesNoJobAndTheTemporaryFilesGo) {
  StartServer();
  const std::string photo = SyntheticJpeg(640, 480, 5);
  const std::string body = Multipart({{"images", "a.jpg", photo}, {"images", "b.jpg", photo}});
  TestClient client(port_);
  ASSERT_TRUE(client.Write(std::string("POST /api/v1/jobs HTTP/1.1\r\nHost: x\r\n") +
                           "Content-Type: multipart/form-data; boundary=" + kBoundary +
                           "\r\nContent-Length: " + std::to_string(body.size()) + "\r\n\r\n" +
                           body.substr(0, body.size() * 3 / 4)));
  // Wait until the server has the second photo's file open.
  bool in_progress = false;
  for (int i = 0; i < 200 && !in_progress; ++i) {
    for (const fs::path& upload : TempEntries()) {
      in_progress |= fs::exists(upload / "input" / "0002.part");
    }
    if (!in_progress) std::this_thread::sleep_for(10ms);
  }
  ASSERT_TRUE(in_progress) << "the upload never reached the second photo";
  server_->Kill();
  EXPECT_FALSE(TempEntries().empty());

  StartServer();
  EXPECT_TRUE(TempEntries().empty());
  EXPECT_NE(server_->Stderr().find("removed the orphaned upload"), std::string::npos)
      << server_->Stderr();
  EXPECT_EQ(Json(Fetch(port_, "GET", "/api/v1/jobs"))["total"], 0);
  EXPECT_TRUE(fs::is_empty(data() / "jobs"));
  // And the server works normally afterwards.
  EXPECT_FALSE(UploadJob().empty());
}

// Issue 12's fault injection: the disk fills during an upload (here: RLIMIT_FSIZE, so a file
// cannot grow past 8 MiB; the database and its log stay below it). The upload gets 503 with
// Retry-After, leaves nothing behind, the job accepted before is untouched, and the server
// goes on serving and accepting uploads that fit.
TEST_F(ApiTest, DiskFullDuringAnUploadAnswers503AndLosesNothing) {
  if (!fs::exists("/usr/bin/prlimit")) GTEST_SKIP() << "no /usr/bin/prlimit (util-linux)";
  StartServer({"--retry-after", "9"}, /*file_size_limit=*/std::int64_t{8} << 20);
  const std::string before = UploadJob();
  ASSERT_FALSE(before.empty());
  const Job kept = *Store().GetJob(before);

  // A JPEG's first bytes (the server sniffs them), then more than the limit: never stored whole.
  std::string big = SyntheticJpeg(320, 240, 3);
  std::mt19937 random(3);
  while (big.size() < (std::size_t{9} << 20)) big.push_back(static_cast<char>(random()));
  const TestResponse full = Upload({{"images", "big.jpg", big}});
  EXPECT_EQ(full.status, 503u) << full.body << full.error << "\n" << server_->Stderr();
  EXPECT_EQ(full.Header("Retry-After"), "9");
  EXPECT_NE(ErrorMessage(full).find("out of disk space"), std::string::npos) << full.body;
  for (int i = 0; i < 100 && !TempEntries().empty(); ++i) std::this_thread::sleep_for(10ms);
  EXPECT_TRUE(TempEntries().empty());

  EXPECT_EQ(Json(Fetch(port_, "GET", "/api/v1/jobs"))["total"], 1);
  const Job after = *Store().GetJob(before);
  EXPECT_EQ(after.state, kept.state);
  EXPECT_EQ(after.image_count, kept.image_count);
  const std::vector<JobImageRecord> images = *Store().ListImages(before);
  ASSERT_EQ(images.size(), 2u);
  for (const JobImageRecord& image : images) {
    EXPECT_TRUE(fs::exists(data() / "jobs" / before / "input" / image.stored_name));
  }
  EXPECT_EQ(Fetch(port_, "GET", "/healthz").status, 200u);
  EXPECT_FALSE(UploadJob().empty()) << server_->Stderr();
}

// The long random server-kill test (issue 12; ctest entry tests/api_random_kill_test, label
// long, which sets RECONDUIT_LONG_TESTS=1; skipped in the regular run). Four clients upload
// three-photo jobs again and again while the server is killed by SIGKILL after a uniform random
// 0.05-2 s, RECONDUIT_SERVER_KILLS times (default 10), and started again each time. At the end
// every upload that was answered 201 is a job whose photos are on disk byte for byte; every job
// the store lists is whole (a row for each photo, each photo's file of the recorded size; a job
// whose 201 was lost in the kill counts, as long as it is whole); no folder is left that no job
// owns, nothing in tmp/; the server goes on accepting uploads. RECONDUIT_RANDOM_SEED repeats a
// run.
TEST_F(ApiTest, RandomServerKillsDuringUploadsLoseNothing) {
  if (!testing_util::LongTestsEnabled()) {
    GTEST_SKIP() << "a long test: ctest -L long -R api_random_kill (RECONDUIT_LONG_TESTS=1)";
  }
  const int kills = static_cast<int>(testing_util::EnvLong("RECONDUIT_SERVER_KILLS", 10));
  const auto seed =
      static_cast<unsigned>(testing_util::EnvLong("RECONDUIT_RANDOM_SEED", std::random_device()()));
  std::printf("server kills: %d, seed %u (RECONDUIT_RANDOM_SEED repeats it)\n", kills, seed);
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> life_ms(50, 2000);

  // Photos differ per upload (a seed each), so each accepted job's files can be told apart.
  std::mutex mutex;
  std::map<std::string, std::vector<std::string>> accepted;  // Job id -> its photos' bytes.
  int attempts = 0, full = 0, cut = 0;
  std::atomic<int> next_seed{1};
  const auto uploader = [&](std::atomic<bool>& stop) {
    while (!stop) {
      std::vector<std::string> photos;
      for (int i = 0; i < 3; ++i) photos.push_back(SyntheticJpeg(480, 360, next_seed++));
      const TestResponse response = Fetch(port_, "POST", "/api/v1/jobs", MultipartHeaders(),
                                          Multipart({{"images", "a.jpg", photos[0]},
                                                     {"images", "b.jpg", photos[1]},
                                                     {"images", "c.jpg", photos[2]}}));
      std::lock_guard lock(mutex);
      ++attempts;
      if (response.status == 201) {
        accepted[Json(response).value("id", "")] = photos;
      } else if (response.status == 0) {
        ++cut;  // The server died under it.
      } else if ((response.status == 429 || response.status == 503) &&
                 !response.Header("Retry-After").empty()) {
        ++full;  // The queue is full: a correct answer.
      } else {
        ADD_FAILURE() << response.status << " " << response.body;
      }
    }
  };
  for (int k = 0; k < kills; ++k) {
    StartServer();
    std::atomic<bool> stop{false};
    std::vector<std::thread> clients;
    for (int c = 0; c < 4; ++c) clients.emplace_back(uploader, std::ref(stop));
    std::this_thread::sleep_for(std::chrono::milliseconds(life_ms(random)));
    server_->Kill();
    stop = true;
    for (std::thread& client : clients) client.join();
  }
  StartServer();
  EXPECT_TRUE(TempEntries().empty());

  // Every 201 is a job with its photos, byte for byte.
  for (const auto& [id, photos] : accepted) {
    SCOPED_TRACE("accepted job " + id);
    const TestResponse status = Fetch(port_, "GET", "/api/v1/jobs/" + id);
    ASSERT_EQ(status.status, 200u) << status.body;
    const Result<std::vector<JobImageRecord>> rows = Store().ListImages(id);
    ASSERT_TRUE(rows.ok()) << rows.status();
    ASSERT_EQ(rows->size(), photos.size());
    for (std::size_t i = 0; i < photos.size(); ++i) {
      EXPECT_EQ(ReadFileBytes(data() / "jobs" / id / "input" / (*rows)[i].stored_name), photos[i]);
    }
  }
  // Every listed job is whole; every job folder has its job.
  std::vector<Job> jobs;
  JobListQuery query;
  query.limit = 1000;
  for (;; query.offset += query.limit) {
    const Result<JobPage> page = Store().ListJobs(query);
    ASSERT_TRUE(page.ok()) << page.status();
    jobs.insert(jobs.end(), page->jobs.begin(), page->jobs.end());
    if (page->jobs.size() < static_cast<std::size_t>(query.limit)) break;
  }
  std::set<std::string> listed;
  for (const Job& job : jobs) {
    listed.insert(job.id);
    const Result<std::vector<JobImageRecord>> rows = Store().ListImages(job.id);
    ASSERT_TRUE(rows.ok()) << rows.status();
    EXPECT_EQ(rows->size(), 3u) << job.id;
    for (const JobImageRecord& row : *rows) {
      const fs::path file = data() / "jobs" / job.id / "input" / row.stored_name;
      ASSERT_TRUE(fs::exists(file)) << file;
      EXPECT_EQ(static_cast<std::int64_t>(fs::file_size(file)), row.photo.bytes) << file;
    }
  }
  std::set<std::string> folders;
  for (const auto& entry : fs::directory_iterator(data() / "jobs")) {
    folders.insert(entry.path().filename().string());
  }
  EXPECT_EQ(folders, listed);
  EXPECT_GE(listed.size(), accepted.size());
  EXPECT_FALSE(UploadJob().empty()) << server_->Stderr();
  std::printf(
      "server kills: %d; %d uploads: %zu answered 201, %d cut by a kill, %d refused as the "
      "queue was full; %zu jobs listed after the restarts (%zu accepted without the client "
      "hearing it), all whole\n",
      kills, attempts, accepted.size(), cut, full, listed.size(), listed.size() - accepted.size());
}

// True when this process may make mount namespaces and mount in them (root with unshare, as on
// the project's machines and CI); the tests that need a mount of their own skip otherwise.
bool CanMountPrivately() {
  return ::geteuid() == 0 &&
         std::system("/usr/bin/unshare -m --propagation private true >/dev/null 2>&1") == 0;
}

// Issue 12's fault injection: the database file is read-only (a read-only bind mount in a mount
// namespace of the server's own). The server starts and says so; reads go on (status, list);
// uploads are refused with 503, Retry-After and a message naming the read-only database, and
// leave nothing behind; the job accepted before is untouched; once the file is writable again,
// uploads are accepted.
TEST_F(ApiTest, ReadOnlyDatabaseRefusesUploadsCleanly) {
  if (!CanMountPrivately()) GTEST_SKIP() << "needs root and unshare -m (util-linux)";
  StartServer();
  const std::string before = UploadJob();
  ASSERT_FALSE(before.empty());
  ASSERT_EQ(server_->Terminate(10s), 0);
  const std::string db = (data() / "reconduit.db").string();
  StartServer({}, 0,
              {"/usr/bin/unshare", "-m", "--propagation", "private", "/bin/sh", "-c",
               "mount --bind '" + db + "' '" + db + "' && mount -o remount,ro,bind '" + db +
                   "' && exec \"$@\"",
               "sh"});
  EXPECT_NE(server_->Stderr().find("is read-only: jobs can be read"), std::string::npos)
      << server_->Stderr();
  const TestResponse status = Fetch(port_, "GET", "/api/v1/jobs/" + before);
  EXPECT_EQ(status.status, 200u) << status.body;
  EXPECT_EQ(Json(Fetch(port_, "GET", "/api/v1/jobs"))["total"], 1);
  const TestResponse refused = Upload({{"images", "a.jpg", SyntheticJpeg(320, 240, 7)},
                                       {"images", "b.jpg", SyntheticJpeg(320, 240, 8)}});
  std::printf("upload with a read-only database: %u %s\n", refused.status, refused.body.c_str());
  EXPECT_EQ(refused.status, 503u) << refused.body;
  EXPECT_FALSE(refused.Header("Retry-After").empty());
  EXPECT_NE(ErrorMessage(refused).find("read-only"), std::string::npos) << refused.body;
  const TestResponse cancel = Fetch(port_, "POST", "/api/v1/jobs/" + before + "/cancel");
  EXPECT_EQ(cancel.status, 503u) << cancel.body;
  for (int i = 0; i < 100 && !TempEntries().empty(); ++i) std::this_thread::sleep_for(10ms);
  EXPECT_TRUE(TempEntries().empty());
  EXPECT_EQ(Fetch(port_, "GET", "/healthz").status, 200u);

  // Writable again (a server outside the namespace): nothing was lost, uploads go through.
  ASSERT_EQ(server_->Terminate(10s), 0);
  StartServer();
  const Job kept = *Store().GetJob(before);
  EXPECT_EQ(kept.state, JobState::kQueued);
  EXPECT_EQ(kept.image_count, 2);
  EXPECT_FALSE(UploadJob().empty()) << server_->Stderr();
  EXPECT_EQ(Json(Fetch(port_, "GET", "/api/v1/jobs"))["total"], 2);
}

// Issue 12's fault injection: another process holds the database's write lock. Uploads are
// refused with a clear retryable answer once the store's wait runs out; reads go on (WAL);
// when the lock goes, uploads are accepted again and nothing accepted before is lost.
TEST_F(ApiTest, DatabaseLockedByAnotherProcessRefusesUploadsCleanly) {
  StartServer();
  const std::string before = UploadJob();
  ASSERT_FALSE(before.empty());
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((data() / "reconduit.db").string().c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "BEGIN EXCLUSIVE", nullptr, nullptr, nullptr), SQLITE_OK);
  const auto start = std::chrono::steady_clock::now();
  const TestResponse locked = Upload({{"images", "a.jpg", SyntheticJpeg(320, 240, 7)},
                                      {"images", "b.jpg", SyntheticJpeg(320, 240, 8)}});
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("upload while the database is locked: %u in %.1f s: %s\n", locked.status, seconds,
              locked.body.c_str());
  EXPECT_EQ(locked.status, 503u) << locked.body;
  EXPECT_FALSE(locked.Header("Retry-After").empty());
  EXPECT_NE(ErrorMessage(locked).find("busy"), std::string::npos) << locked.body;
  const TestResponse status = Fetch(port_, "GET", "/api/v1/jobs/" + before);
  EXPECT_EQ(status.status, 200u) << status.body;
  EXPECT_EQ(Fetch(port_, "GET", "/healthz").status, 200u);
  ASSERT_EQ(sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);

  EXPECT_TRUE(TempEntries().empty());
  EXPECT_FALSE(UploadJob().empty()) << server_->Stderr();
  EXPECT_EQ(Json(Fetch(port_, "GET", "/api/v1/jobs"))["total"], 2);
}

TEST_F(ApiTest, FiftyConcurrentUploadsGetCreatedOrRetryLaterNeverAServerError) {
  StartServer({"--max-concurrent-uploads", "8", "--max-connections", "256"});
  const std::string body = Multipart({{"images", "a.jpg", SyntheticJpeg(320, 240, 9)},
                                      {"images", "b.jpg", SyntheticJpeg(320, 240, 10)}});
  constexpr int kClients = 50;
  std::vector<TestResponse> responses(kClients);
  std::vector<std::thread> threads;
  std::atomic<bool> go{false};
  for (int i = 0; i < kClients; ++i) {
    threads.emplace_back([&, i] {
      while (!go) std::this_thread::yield();
      responses[i] = Fetch(port_, "POST", "/api/v1/jobs", MultipartHeaders(), body);
    });
  }
  go = true;
  for (std::thread& thread : threads) thread.join();

  int created = 0;
  int busy = 0;
  for (const TestResponse& response : responses) {
    ASSERT_TRUE(response.status == 201u || response.status == 429u || response.status == 503u)
        << response.status << " " << response.error << " " << response.body;
    if (response.status == 201u) {
      ++created;
    } else {
      ++busy;
      EXPECT_FALSE(response.Header("Retry-After").empty());
    }
  }
  EXPECT_GE(created, 1);
  EXPECT_EQ(Json(Fetch(port_, "GET", "/api/v1/jobs?limit=100"))["total"], created);
  EXPECT_TRUE(TempEntries().empty());
  EXPECT_EQ(server_->Stderr().find("database is locked"), std::string::npos);
  std::cout << "50 concurrent uploads: " << created << " created, " << busy
            << " told to retry later\n";
}

}  // namespace
}  // namespace reconduit
