// The XML writer: the layout both generated formats rely on, and escaping that keeps names which would break XML
// (quotes, angle brackets, ampersands, control characters, "--" in comments) readable back exactly by an XML parser.
#include "cellwright/common/xml.hpp"

#include <gtest/gtest.h>
#include <tinyxml2.h>

#include <string>

#include "cellwright/common/error.hpp"

namespace cellwright::xml {
namespace {

TEST(XmlWriter, LaysOutElementsOnePerLineIndentedByLevel) {
  Writer w(2);
  w.open("mujoco", {{"model", "cell"}});
  w.comment("robot 'puma'");
  w.open("worldbody");
  w.leaf("geom", {{"name", "floor"}, {"size", "1 1 0.1"}});
  w.close();
  w.text_element("name", "x");
  w.close();
  EXPECT_EQ(w.str(),
            "<mujoco model=\"cell\">\n"
            "  <!-- robot 'puma' -->\n"
            "  <worldbody>\n"
            "    <geom name=\"floor\" size=\"1 1 0.1\"/>\n"
            "  </worldbody>\n"
            "  <name>x</name>\n"
            "</mujoco>\n");
}

TEST(XmlWriter, DeclarationIntegersAndFourSpacesByDefault) {
  Writer w;
  w.declaration("xml version=\"1.0\" encoding=\"UTF-8\"");
  w.open("net");
  w.attribute("capacity", 3u);
  w.attribute("line", -7);
  w.open("page");
  w.close();
  w.close();
  EXPECT_EQ(w.str(),
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
            "<net capacity=\"3\" line=\"-7\">\n"
            "    <page/>\n"
            "</net>\n");
}

TEST(XmlWriter, EscapesAttributesAndText) {
  EXPECT_EQ(Writer::escape_attribute("a\"b<c>&d"), "a&quot;b&lt;c&gt;&amp;d");
  EXPECT_EQ(Writer::escape_attribute("tab\tnl\ncr\r"), "tab&#9;nl&#10;cr&#13;");
  EXPECT_EQ(Writer::escape_attribute(std::string("bell\x07", 5)), "bell&#7;");
  EXPECT_EQ(Writer::escape_attribute("it's"), "it's");
  Writer w;
  w.text_element("t", "1 < 2\n& more");
  EXPECT_EQ(w.str(), "<t>1 &lt; 2\n&amp; more</t>");  // a root holding text: no newline after it
  Writer blank;
  blank.text_element("t", " \n");  // only white space: kept as references, which readers do not drop
  EXPECT_EQ(blank.str(), "<t>&#32;&#10;</t>");
}

// Names that would break XML come back from a real parser exactly as given.
TEST(XmlWriter, HostileNamesReadBackExactly) {
  const std::string names[] = {"\"><evil attr=\"",
                               "a&b;&amp;",
                               "</net>",
                               "line\nbreak\ttab\rcr",
                               "  ",
                               "--x--",
                               std::string("nul-free\x01\x1f", 10)};
  for (const std::string& name : names) {
    Writer w;
    w.open("root");
    w.attribute("name", name);
    w.comment(name);
    w.text_element("text", name);
    w.close();
    tinyxml2::XMLDocument doc(true, tinyxml2::PRESERVE_WHITESPACE);
    ASSERT_EQ(doc.Parse(w.str().c_str()), tinyxml2::XML_SUCCESS) << w.str();
    const tinyxml2::XMLElement* root = doc.RootElement();
    ASSERT_NE(root, nullptr);
    EXPECT_EQ(std::string(root->Attribute("name")), name) << w.str();
    const char* text = root->FirstChildElement("text")->GetText();
    EXPECT_EQ(std::string(text ? text : ""), name) << w.str();
    // A comment may not hold "--": the writer separates the dashes, and the document stays well-formed.
    const tinyxml2::XMLComment* comment = root->FirstChild()->ToComment();
    ASSERT_NE(comment, nullptr);
    EXPECT_EQ(std::string(comment->Value()).find("--"), std::string::npos);
  }
}

TEST(XmlWriter, UnbalancedUseIsOurBug) {
  Writer w;
  EXPECT_THROW(w.close(), InternalError);
  EXPECT_THROW(w.attribute("a", "b"), InternalError);
  w.open("a");
  EXPECT_THROW((void)w.str(), InternalError);
}

}  // namespace
}  // namespace cellwright::xml
