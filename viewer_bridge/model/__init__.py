"""The neutral model in the middle: the scene, its poses and times, and the models beside it
(contacts, images), with what lowers them for the formats."""
