#include "net/untrusted_text.h"

#include <gtest/gtest.h>

#include <string>

#include "net/wire_error.h"

namespace sculpt::server {
namespace {

TEST(UntrustedTextTest, KeepsPlainTextAndUtf8) {
  EXPECT_EQ(Printable("alice"), "alice");
  EXPECT_EQ(Printable("caf\xc3\xa9 \xe2\x86\x92"), "caf\xc3\xa9 \xe2\x86\x92");
}

TEST(UntrustedTextTest, EscapesLineBreaksSoALogLineCannotBeForged) {
  const std::string s = Printable("bye\n[2026-11-23 12:00:00] [info] forged\r\x1b[31m");
  EXPECT_EQ(s.find('\n'), std::string::npos);
  EXPECT_EQ(s.find('\r'), std::string::npos);
  EXPECT_EQ(s.find('\x1b'), std::string::npos);
  EXPECT_NE(s.find("bye\\x0a[2026"), std::string::npos) << s;
  EXPECT_NE(s.find("\\x1b"), std::string::npos) << s;
}

TEST(UntrustedTextTest, EscapesBackslashAndInvalidUtf8) {
  EXPECT_EQ(Printable("a\\x0a"), "a\\x5cx0a");
  EXPECT_EQ(Printable("\xff\xc3"), "\\xff\\xc3");     // a lone lead byte at the end
  EXPECT_EQ(Printable("\xc0\xaf"), "\\xc0\\xaf");     // overlong '/'
  EXPECT_EQ(Printable("\xed\xa0\x80"), "\\xed\\xa0\\x80");  // a surrogate
}

TEST(UntrustedTextTest, CutsLongTextAtACharacterBoundaryAndGivesTheLength) {
  const std::string mb(1 << 20, 'x');
  const std::string s = Printable(mb, 64);
  EXPECT_EQ(s, std::string(64, 'x') + "...(1048576 bytes)");
  // A two-byte character straddling the bound is left out whole.
  const std::string t = Printable(std::string(63, 'a') + "\xc3\xa9" + "b", 64);
  EXPECT_EQ(t, std::string(63, 'a') + "...(66 bytes)");
}

TEST(UntrustedTextTest, WireErrorsQuoteAtMostABoundedValue) {
  const std::string name(1 << 20, 'n');
  const v1::Error e = ProtocolError(v1::ERROR_CODE_NOT_FOUND, "JoinScene.scene", name,
                                    "{" + name + "}", "unknown scene " + name);
  EXPECT_LE(e.value().size(), kMaxErrorFieldBytes + 24);
  EXPECT_LE(e.allowed_range().size(), kMaxErrorTextBytes + 24);
  EXPECT_LE(e.message().size(), kMaxErrorTextBytes + 24);
  EXPECT_LT(e.ByteSizeLong(), 2048u);
}

}  // namespace
}  // namespace sculpt::server
