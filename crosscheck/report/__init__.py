"""What a run's results become for people and CI: the checked inputs, the content of each page,
and its HTML, Markdown and JUnit renderings with their figures."""
