"""Impact markers: timeline markers carrying an impact, their operators, and keeping them in step with the timeline."""
