"""LCM: schemas (`schema`), codecs compiled from them (`serde`; the project's types in `codecs`,
compiled when first imported), any type's store (`library`), and its ROS 2 mapping, CDR and JSON.
"""
