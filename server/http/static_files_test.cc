#include "server/http/static_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <unistd.h>

namespace reconduit::server {
namespace {

namespace fs = std::filesystem;

class StaticFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    base_ = fs::temp_directory_path() /
            ("reconduit_static_test_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(base_);
    root_ = base_ / "web";
    fs::create_directories(root_ / "js");
    fs::create_directories(root_ / "docs");
    Write(root_ / "index.html", "<html>home</html>");
    Write(root_ / "js" / "app.js", "console.log(1)");
    Write(root_ / "docs" / "index.html", "docs");
    Write(root_ / "model v2.glb", "glTF");
    Write(root_ / ".env", "SECRET=1");
    Write(base_ / "secret.txt", "top secret");
  }
  void TearDown() override { fs::remove_all(base_); }

  static void Write(const fs::path& path, const std::string& content) {
    std::ofstream(path, std::ios::binary) << content;
  }

  StatusCode Code(std::string_view raw_path) {
    return ResolveStaticPath(root_, raw_path).status().code();
  }

  fs::path base_;
  fs::path root_;
};

TEST_F(StaticFilesTest, ResolvesFilesAndIndexes) {
  Result<fs::path> path = ResolveStaticPath(root_, "/");
  ASSERT_TRUE(path.ok()) << path.status();
  EXPECT_EQ(*path, fs::canonical(root_ / "index.html"));
  EXPECT_EQ(*ResolveStaticPath(root_, "/js/app.js"), fs::canonical(root_ / "js" / "app.js"));
  EXPECT_EQ(*ResolveStaticPath(root_, "/docs/"), fs::canonical(root_ / "docs" / "index.html"));
  EXPECT_EQ(*ResolveStaticPath(root_, "/model%20v2.glb"), fs::canonical(root_ / "model v2.glb"));
}

TEST_F(StaticFilesTest, MissingFilesAndFoldersAreNotFound) {
  EXPECT_EQ(Code("/nope.html"), StatusCode::kNotFound);
  EXPECT_EQ(Code("/js"), StatusCode::kNotFound);   // A folder without trailing slash.
  EXPECT_EQ(Code("/js/"), StatusCode::kNotFound);  // No index.html there.
  EXPECT_EQ(ResolveStaticPath(base_ / "missing", "/").status().code(), StatusCode::kNotFound);
}

TEST_F(StaticFilesTest, RefusesTraversal) {
  for (const char* attack :
       {"/../secret.txt", "/js/../../secret.txt", "/%2e%2e/secret.txt", "/%2E%2E/secret.txt",
        "/.%2e/secret.txt", "/..%2fsecret.txt", "/js%2f..%2f..%2fsecret.txt", "/..%5csecret.txt",
        "//etc/passwd", "/js//app.js", "/./index.html", "/.env", "/%2eenv", "/index.html%00.png"}) {
    SCOPED_TRACE(attack);
    const StatusCode code = Code(attack);
    EXPECT_TRUE(code == StatusCode::kInvalidArgument) << StatusCodeName(code);
  }
  // Not an absolute path at all.
  EXPECT_EQ(Code("etc/passwd"), StatusCode::kInvalidArgument);
  EXPECT_EQ(Code(""), StatusCode::kInvalidArgument);
}

TEST_F(StaticFilesTest, RefusesSymlinkOutOfTheRoot) {
  fs::create_symlink(base_ / "secret.txt", root_ / "link.txt");
  EXPECT_EQ(Code("/link.txt"), StatusCode::kInvalidArgument);
  fs::create_symlink(root_ / "index.html", root_ / "inside.html");
  EXPECT_TRUE(ResolveStaticPath(root_, "/inside.html").ok());
}

TEST_F(StaticFilesTest, HandlerAnswersFilesAndJsonErrors) {
  const Handler handler = MakeStaticFileHandler(root_);
  RequestContext context;
  context.path = "/js/app.js";
  Response response = handler(context);
  EXPECT_EQ(response.status(), HttpStatus::ok);
  ASSERT_TRUE(response.file().has_value());
  EXPECT_EQ(*response.FindHeader("Content-Type"), "text/javascript; charset=utf-8");

  context.path = "/missing.css";
  response = handler(context);
  EXPECT_EQ(response.status(), HttpStatus::not_found);
  EXPECT_EQ(nlohmann::json::parse(response.body())["error"]["code"], "not_found");

  context.path = "/%2e%2e/secret.txt";
  response = handler(context);
  EXPECT_EQ(response.status(), HttpStatus::bad_request);
  EXPECT_FALSE(response.file().has_value());
  EXPECT_EQ(response.body().find("top secret"), std::string::npos);
}

// Issue 12: the page had no Content-Security-Policy. Its inline import map (what the three.js
// view uses) is allowed by hash, its own module scripts by 'self'; other files get none.
TEST_F(StaticFilesTest, PagesCarryAContentSecurityPolicy) {
  const std::string map = "\n    {\"imports\": {\"three\": \"./vendor/three.module.js\"}}\n  ";
  Write(root_ / "page.html", "<html><head><script type=\"importmap\">" + map +
                                 "</script><SCRIPT type=\"module\" src=\"app.js\"></SCRIPT>"
                                 "</head></html>");
  const Handler handler = MakeStaticFileHandler(root_);
  RequestContext context;
  context.path = "/page.html";
  const Response page = handler(context);
  ASSERT_NE(page.FindHeader("Content-Security-Policy"), nullptr);
  const std::string policy = *page.FindHeader("Content-Security-Policy");
  // python3: base64(sha256(map)).
  EXPECT_NE(
      policy.find("script-src 'self' 'sha256-Xqp4IuITNLZX3BFKNsu0WEcblwQ8O90+57eSzl4FzIU='; "),
      std::string::npos)
      << policy;
  EXPECT_NE(policy.find("default-src 'self'"), std::string::npos);
  EXPECT_NE(policy.find("object-src 'none'"), std::string::npos);
  EXPECT_NE(policy.find("frame-ancestors 'none'"), std::string::npos);
  EXPECT_EQ(policy.find("unsafe"), std::string::npos);
  // No inline script: 'self' alone.
  EXPECT_NE(ContentSecurityPolicy("<script src=\"a.js\"></script>").find("script-src 'self';"),
            std::string::npos);

  context.path = "/js/app.js";
  EXPECT_EQ(handler(context).FindHeader("Content-Security-Policy"), nullptr);
}

// Issue 12: with a bearer token the page's own files are public (a browser cannot send the
// token with a navigation or a script load). Exactly what the handler serves is listed: not
// hidden files or folders, not what a symlink reaches outside the root.
TEST_F(StaticFilesTest, ListsTheRequestPathsOfTheServedFiles) {
  fs::create_directories(root_ / ".deps" / "three");
  Write(root_ / ".deps" / "three" / "three.module.js", "hidden");
  fs::create_symlink(base_ / "secret.txt", root_ / "link.txt");
  Write(root_ / "100% #1?.txt", "odd name");
  EXPECT_EQ(StaticFilePaths(root_),
            (std::vector<std::string>{"/", "/100%25%20%231%3F.txt", "/docs/", "/docs/index.html",
                                      "/index.html", "/js/app.js", "/model%20v2.glb"}));
  // Each listed path is one the handler answers with its file.
  const Handler handler = MakeStaticFileHandler(root_);
  for (const std::string& path : StaticFilePaths(root_)) {
    RequestContext context;
    context.path = path;
    EXPECT_EQ(handler(context).status(), HttpStatus::ok) << path;
  }
  EXPECT_TRUE(StaticFilePaths(base_ / "missing").empty());
}

}  // namespace
}  // namespace reconduit::server
