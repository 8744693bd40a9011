"""Drake's LCM messages to and from the neutral models, one module per message family: `load`
(lcmt_viewer_load_robot and its link data, with the table of mappings/drake.yaml), `draw`
(lcmt_viewer_draw, with the fast decoder and encoder), `contact` (lcmt_contact_results_for_viz)
and `point_cloud` (lcmt_point_cloud)."""
