#include <gtest/gtest.h>

#include "shading/core/suggest.h"

using namespace shading;

TEST(Suggest, EditDistanceCountsEachKindOfEditOnce) {
    EXPECT_EQ(edit_distance("brdf_table", "brdf_table"), 0);
    EXPECT_EQ(edit_distance("brdf_tabel", "brdf_table"), 1);  // two neighbours swapped
    EXPECT_EQ(edit_distance("brdf_tabe", "brdf_table"), 1);   // one letter missing
    EXPECT_EQ(edit_distance("brdf_tablex", "brdf_table"), 1); // one too many
    EXPECT_EQ(edit_distance("brdf_tible", "brdf_table"), 1);  // one replaced
    EXPECT_EQ(edit_distance("MARBLE", "marble"), 0);          // case does not count
    EXPECT_EQ(edit_distance("", "abc"), 3);
    EXPECT_EQ(edit_distance("kitten", "sitting"), 3);
}

TEST(Suggest, ClosestNameIsTheOneMeant) {
    const std::vector<std::string> keywords = {"brdf_model", "brdf_table", "diffuse", "dipole", "phong"};
    EXPECT_EQ(closest_name("brdf_tabel", keywords), "brdf_table");
    EXPECT_EQ(closest_name("brdf_modle", keywords), "brdf_model");
    EXPECT_EQ(closest_name("dipol", keywords), "dipole");
    const std::vector<std::string> media = {"Apple", "Marble", "Skin1", "Skin2", "Ketchup"};
    EXPECT_EQ(closest_name("Marbel", media), "Marble");
    EXPECT_EQ(closest_name("ketchup", media), "Ketchup");
}

TEST(Suggest, NothingWhenNoNameIsClose) {
    const std::vector<std::string> names = {"brdf_table", "diffuse", "phong"};
    EXPECT_EQ(closest_name("sphere", names), "");
    EXPECT_EQ(closest_name("xyz", names), "");
    EXPECT_EQ(closest_name("phong", names), "");  // the word is a name itself
    EXPECT_EQ(closest_name("abc", {}), "");
    // a short word gets one edit at most: "pong" -> "phong", but not "png" -> "phong"
    EXPECT_EQ(closest_name("pong", names), "phong");
    EXPECT_EQ(closest_name("png", names), "");
}

TEST(Suggest, TiesGoToTheNameListedFirst) {
    EXPECT_EQ(closest_name("Skin", {"Skin1", "Skin2"}), "Skin1");
}
